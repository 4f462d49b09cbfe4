// mmetric's std::sort of a point cloud's positions (equ / eqTFAN --outputModelA/B), replayed on the points' ranks:
// libstdc++'s introsort step for step (median-of-three quicksort down to 16-element runs, heapsort past a depth of
// 2 * floor(log2(n)), then insertion sort), the algorithm of the GCC build of mmetric v1.1.7.
//
// Written out here rather than calling this build's std::sort: the permutation std::sort leaves among equal elements
// is its implementation's (libc++ and MSVC's differ from libstdc++'s), and the file mmetric writes depends on it. It
// is the same algorithm as torchmeshmetric.mpeg.comparison.point_order._introsort, the Python reference the tests
// compare it with. Compiled into the "pcc" extension (mpeg_pcc.cpp binds it).
#include <torch/extension.h>

#include <cstdint>
#include <utility>
#include <vector>

namespace {

constexpr int64_t THRESHOLD = 16;  // libstdc++'s _S_threshold

class Introsort {
 public:
  Introsort(const int64_t* rank, int64_t n) : rank_(rank), a_(n) {
    for (int64_t i = 0; i < n; ++i) a_[i] = i;
  }

  std::vector<int64_t> run() {
    const int64_t n = static_cast<int64_t>(a_.size());
    int64_t depth = 0;
    for (int64_t m = n; m > 1; m >>= 1) ++depth;  // floor(log2(n))
    loop(0, n, 2 * depth);
    if (n > THRESHOLD) {
      insertion_sort(0, THRESHOLD);
      for (int64_t i = THRESHOLD; i < n; ++i) linear_insert(i);
    } else if (n > 0) {
      insertion_sort(0, n);
    }
    return std::move(a_);
  }

 private:
  bool less(int64_t i, int64_t j) const { return rank_[i] < rank_[j]; }

  void adjust_heap(int64_t first, int64_t hole, int64_t length, int64_t value) {
    const int64_t top = hole;
    int64_t child = hole;
    while (child < (length - 1) / 2) {
      child = 2 * (child + 1);
      if (less(a_[first + child], a_[first + child - 1])) --child;
      a_[first + hole] = a_[first + child];
      hole = child;
    }
    if (length % 2 == 0 && child == (length - 2) / 2) {
      child = 2 * (child + 1);
      a_[first + hole] = a_[first + child - 1];
      hole = child - 1;
    }
    int64_t parent = (hole - 1) / 2;
    while (hole > top && less(a_[first + parent], value)) {
      a_[first + hole] = a_[first + parent];
      hole = parent;
      parent = (hole - 1) / 2;
    }
    a_[first + hole] = value;
  }

  void heap_sort(int64_t first, int64_t last) {  // std::__partial_sort(first, last, last): make_heap, sort_heap
    const int64_t length = last - first;
    if (length >= 2) {
      for (int64_t parent = (length - 2) / 2; parent >= 0; --parent) {
        adjust_heap(first, parent, length, a_[first + parent]);
      }
    }
    while (last - first > 1) {
      --last;
      const int64_t value = a_[last];
      a_[last] = a_[first];
      adjust_heap(first, 0, last - first, value);
    }
  }

  void median_to_first(int64_t result, int64_t x, int64_t y, int64_t z) {
    int64_t m;
    if (less(a_[x], a_[y])) {
      m = less(a_[y], a_[z]) ? y : (less(a_[x], a_[z]) ? z : x);
    } else if (less(a_[x], a_[z])) {
      m = x;
    } else {
      m = less(a_[y], a_[z]) ? z : y;
    }
    std::swap(a_[result], a_[m]);
  }

  int64_t partition(int64_t first, int64_t last, int64_t pivot) {
    while (true) {
      while (less(a_[first], a_[pivot])) ++first;
      --last;
      while (less(a_[pivot], a_[last])) --last;
      if (!(first < last)) return first;
      std::swap(a_[first], a_[last]);
      ++first;
    }
  }

  void loop(int64_t first, int64_t last, int64_t depth) {
    while (last - first > THRESHOLD) {
      if (depth == 0) {
        heap_sort(first, last);
        return;
      }
      --depth;
      median_to_first(first, first + 1, first + (last - first) / 2, last - 1);
      const int64_t cut = partition(first + 1, last, first);
      loop(cut, last, depth);
      last = cut;
    }
  }

  void linear_insert(int64_t last) {  // unguarded: an element not above it exists to its left
    const int64_t value = a_[last];
    int64_t next = last - 1;
    while (less(value, a_[next])) {
      a_[last] = a_[next];
      last = next;
      --next;
    }
    a_[last] = value;
  }

  void insertion_sort(int64_t first, int64_t last) {
    for (int64_t i = first + 1; i < last; ++i) {
      if (less(a_[i], a_[first])) {
        const int64_t value = a_[i];
        for (int64_t k = i; k > first; --k) a_[k] = a_[k - 1];
        a_[first] = value;
      } else {
        linear_insert(i);
      }
    }
  }

  const int64_t* rank_;
  std::vector<int64_t> a_;
};

}  // namespace

// The permutation libstdc++'s std::sort leaves on range(n) ordered by rank: (n,) int64 ranks in, (n,) int64 out.
torch::Tensor introsort_permutation(const torch::Tensor& rank) {
  TORCH_CHECK(rank.dim() == 1 && rank.scalar_type() == torch::kInt64 && rank.is_contiguous() &&
                  rank.device().is_cpu(),
              "introsort_permutation: a contiguous (n,) int64 CPU tensor expected");
  const int64_t n = rank.size(0);
  std::vector<int64_t> a;
  {
    pybind11::gil_scoped_release release;
    a = Introsort(rank.data_ptr<int64_t>(), n).run();
  }
  torch::Tensor out = torch::empty({n}, torch::kInt64);
  std::copy(a.begin(), a.end(), out.data_ptr<int64_t>());
  return out;
}
