// Scheduling of the C++ kernels' loops on torch's thread pool, shared by every extension of native/.
#pragma once

#include <ATen/Parallel.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

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

// std::sort of `v` in one block per thread, the blocks then merged (the result is std::sort's: a total order of
// distinct keys leaves one possible order).
template <typename T>
inline void parallel_sort(std::vector<T>& v) {
  const int64_t n = static_cast<int64_t>(v.size());
  const int64_t blocks = std::max<int64_t>(1, std::min<int64_t>(at::get_num_threads(), n / 65536));
  at::parallel_for(0, blocks, 1, [&](int64_t b, int64_t e) {
    for (int64_t k = b; k < e; ++k) std::sort(v.begin() + k * n / blocks, v.begin() + (k + 1) * n / blocks);
  });
  for (int64_t width = 1; width < blocks; width *= 2)
    for (int64_t k = 0; k + width < blocks; k += 2 * width)
      std::inplace_merge(v.begin() + k * n / blocks, v.begin() + (k + width) * n / blocks,
                         v.begin() + std::min(blocks, k + 2 * width) * n / blocks);
}

}  // namespace tmm
