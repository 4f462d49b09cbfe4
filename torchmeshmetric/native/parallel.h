// Scheduling of the C++ kernels' loops on torch's thread pool, shared by bvh.cpp and deformation_energy.cpp.
#pragma once

#include <ATen/Parallel.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <memory>

namespace tmm {

// fn(begin, end) over [0, n) in chunks of `chunk` items on torch's threads (inline on one). Thread w owns the w-th
// contiguous segment of chunks and takes them front to back; once its own segment is done it takes the chunks left in
// the others', so a preempted thread does not hold the rest. Owning a segment keeps each thread on the same part of
// the data from phase to phase (items are ordered by vertex, see energy_layout): a step's phases are ~100 us of
// short items, and reading what the other core has just written costs more than the items themselves.
template <typename F>
inline void chunked_for(int64_t n, int64_t chunk, const F& fn) {
  const int64_t num_chunks = (n + chunk - 1) / chunk;
  const int64_t workers = std::min<int64_t>(at::get_num_threads(), num_chunks);
  if (workers <= 1) {
    if (n > 0) fn(int64_t(0), n);
    return;
  }
  std::unique_ptr<std::atomic<int64_t>[]> next(new std::atomic<int64_t>[workers]);
  for (int64_t w = 0; w < workers; ++w) next[w] = w * num_chunks / workers;
  at::parallel_for(0, workers, 1, [&](int64_t begin, int64_t end) {
    for (int64_t own = begin; own < end; ++own)
      for (int64_t k = 0; k < workers; ++k) {
        const int64_t w = (own + k) % workers, last = (w + 1) * num_chunks / workers;
        for (int64_t c = next[w].fetch_add(1); c < last; c = next[w].fetch_add(1))
          fn(c * chunk, std::min(n, (c + 1) * chunk));
      }
  });
}

}  // namespace tmm
