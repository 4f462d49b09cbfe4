// Bounding volume hierarchies for exact closest-face and nearest-point selection on the CPU.
//
// Compiled by torchmeshmetric.native.loader (torch.utils.cpp_extension.load) with deformation_energy.cpp.
//
// Build: primitives sorted along a 30-bit Morton curve of their box centres (radix sort), then split at the highest
// differing Morton bit (LBVH, Karras 2012; object median when the codes are equal) into leaves of at most LEAF
// primitives; nodes stored depth first (left child follows its parent), bounds computed bottom up.
// One hierarchy per item of a ragged batch, all in one node array.
//
// Face hierarchies are then collapsed into 4-wide nodes whose leaves are blocks of 4 faces measured side by side
// (see "Kept face hierarchy, 4-wide" below).
//
// Query: points processed in Morton order (cache coherence), stack traversal, nearer child first, pruning a node
// when its box is farther than the current best (with a certified slack, see `prune_bound`), dynamic chunks of
// queries on torch's threads (chunked_for, parallel.h).
//
// Exactness: the squared point-triangle distance is computed with the very same floating-point operations, in the
// same order and the same dtype, as `region_candidates` in kernels/triangle.py (edge-segment clamped projections
// and the face-interior projection, on difference vectors), so the selected face is the brute-force argmin,
// lowest face index among equal squared distances. Must be compiled with -ffp-contract=off (no FMA contraction).
#include <torch/extension.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "parallel.h"
#include "triangle.h"

namespace {

using tmm::chunked_for;
using tmm::closest_on_face;
using tmm::face_data;
using tmm::tri_sq_dist;

constexpr int LEAF_FACES = 4;
constexpr int LEAF_POINTS = 32;
// Cheap linear loops run threaded only above this size: on a loaded machine every parallel region costs
// a barrier, which outweighs the work of a few hundred thousand simple iterations.
constexpr int64_t GRAIN_LINEAR = int64_t(1) << 18;
// Queries per scheduling chunk (see chunked_for).
constexpr int64_t QUERY_CHUNK = 256;

template <typename T>
struct Node {
  T lo[3];
  T hi[3];
  int64_t right;  // index of the right child (left child = this + 1); -1 for a leaf
  int64_t start;  // first primitive (leaf) in the permuted order
  int64_t count;  // number of primitives (leaf)
};

// Bounds of an inner node: the union of its children's boxes (left child = node + 1). Shared by both builders and
// the refit, so a built and a refitted hierarchy hold the same boxes.
template <typename T>
inline void union_children(Node<T>* nodes, int64_t node) {
  Node<T>& nd = nodes[node];
  const Node<T>& l = nodes[node + 1];
  const Node<T>& r = nodes[nd.right];
  for (int k = 0; k < 3; ++k) {
    nd.lo[k] = std::min(l.lo[k], r.lo[k]);
    nd.hi[k] = std::max(l.hi[k], r.hi[k]);
  }
}

// A leaf over the primitives [begin, begin + n) with the given bounds.
template <typename T>
inline int64_t set_leaf(std::vector<Node<T>>& nodes, int64_t node, int64_t begin, int64_t n, const T* lo, const T* hi) {
  Node<T>& nd = nodes[node];
  nd.start = begin;
  nd.count = n;
  nd.right = -1;
  for (int k = 0; k < 3; ++k) {
    nd.lo[k] = lo[k];
    nd.hi[k] = hi[k];
  }
  return node;
}

// An inner node over [begin, begin + n) whose children are built (left = node + 1, right): its range and bounds.
template <typename T>
inline int64_t finish_inner(std::vector<Node<T>>& nodes, int64_t node, int64_t begin, int64_t n, int64_t right) {
  Node<T>& nd = nodes[node];
  nd.start = begin;
  nd.count = n;
  nd.right = right;
  union_children(nodes.data(), node);
  return node;
}

inline uint32_t spread10(uint32_t x) {  // 10 bits -> every third bit of 30
  x &= 0x3ffu;
  x = (x | (x << 16)) & 0x30000ffu;
  x = (x | (x << 8)) & 0x300f00fu;
  x = (x | (x << 4)) & 0x30c30c3u;
  x = (x | (x << 2)) & 0x9249249u;
  return x;
}

template <typename T>
inline uint32_t morton(const T* c, const T* lo, const T* inv) {
  uint32_t q[3];
  for (int k = 0; k < 3; ++k) {
    T u = (c[k] - lo[k]) * inv[k];
    u = std::min(std::max(u, T(0)), T(1023));
    q[k] = static_cast<uint32_t>(u);
  }
  return (spread10(q[0]) << 2) | (spread10(q[1]) << 1) | spread10(q[2]);
}

// Stable LSD radix sort of (30-bit code, index) pairs by code: 3 passes of 10 bits. Above RADIX_PARALLEL pairs the
// passes run on torch's threads: each block of the input counts its digits, the counts are turned into per-block
// write offsets (digit-major, block order: the sort stays stable), and each block scatters its own pairs.
constexpr int64_t RADIX_PARALLEL = int64_t(1) << 16;

inline void radix_sort(std::vector<uint32_t>& code, std::vector<int64_t>& idx) {
  const int64_t n = static_cast<int64_t>(code.size());
  if (n < 2) return;
  const int64_t blocks =
      n < RADIX_PARALLEL ? 1 : std::max<int64_t>(1, std::min<int64_t>(at::get_num_threads(), n / (RADIX_PARALLEL / 2)));
  std::vector<uint32_t> code2(n);
  std::vector<int64_t> idx2(n);
  std::vector<int64_t> count(blocks * 1024);
  auto block_lo = [n, blocks](int64_t b) { return n * b / blocks; };
  auto for_blocks = [blocks](const auto& fn) {
    if (blocks == 1)
      fn(int64_t(0));
    else
      at::parallel_for(0, blocks, 1, [&](int64_t b0, int64_t b1) {
        for (int64_t b = b0; b < b1; ++b) fn(b);
      });
  };
  for (int shift = 0; shift < 30; shift += 10) {
    std::fill(count.begin(), count.end(), 0);
    const uint32_t* src = code.data();
    const int64_t* src_idx = idx.data();
    uint32_t* dst_code = code2.data();
    int64_t* dst_idx = idx2.data();
    for_blocks([&](int64_t b) {
      int64_t* c = count.data() + 1024 * b;
      const int64_t hi = block_lo(b + 1);
      for (int64_t i = block_lo(b); i < hi; ++i) ++c[(src[i] >> shift) & 1023u];
    });
    // Exclusive offsets, digit-major then block: digit d of block b starts after all smaller digits and after
    // digit d of the blocks before b.
    int64_t total = 0;
    bool one_bucket = false;
    for (int d = 0; d < 1024; ++d) {
      int64_t digit_total = 0;
      for (int64_t b = 0; b < blocks; ++b) {
        const int64_t c = count[1024 * b + d];
        count[1024 * b + d] = total;
        total += c;
        digit_total += c;
      }
      if (digit_total == n) one_bucket = true;
    }
    if (one_bucket) continue;  // every code has the same digit: the pass would not move anything
    for_blocks([&](int64_t b) {
      int64_t* c = count.data() + 1024 * b;
      const int64_t hi = block_lo(b + 1);
      for (int64_t i = block_lo(b); i < hi; ++i) {
        const uint32_t k = src[i];
        const int64_t dst = c[(k >> shift) & 1023u]++;
        dst_code[dst] = k;
        dst_idx[dst] = src_idx[i];
      }
    });
    code.swap(code2);
    idx.swap(idx2);
  }
}

// Node over the primitives [begin, end) of the Morton-sorted order, depth first (left child = node + 1). Split at
// the highest bit in which the codes of the range differ (a spatial split, Karras 2012); at the object median when
// all codes are equal. Bounds are computed bottom up. Returns the node index. Primitive boxes are read at perm[slot],
// or at the slot itself when perm is null (boxes already stored in sorted order).
template <typename T>
int64_t build_node(std::vector<Node<T>>& nodes, const uint32_t* code, int64_t base, int64_t begin, int64_t end,
                   const T* box_lo, const T* box_hi, const int64_t* perm, int leaf) {
  const int64_t node = static_cast<int64_t>(nodes.size());
  nodes.emplace_back();
  const int64_t n = end - begin;
  if (n <= leaf) {
    constexpr T inf = std::numeric_limits<T>::infinity();
    T lo[3] = {inf, inf, inf}, hi[3] = {-inf, -inf, -inf};
    for (int64_t i = begin; i < end; ++i) {
      const int64_t p = perm != nullptr ? perm[i] : i;
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], box_lo[3 * p + k]);
        hi[k] = std::max(hi[k], box_hi[3 * p + k]);
      }
    }
    return set_leaf(nodes, node, begin, n, lo, hi);
  }
  int64_t mid = begin + n / 2;
  const uint32_t diff = code[begin - base] ^ code[end - 1 - base];
  if (diff != 0) {
    const uint32_t bit = 1u << (31 - __builtin_clz(diff));
    // First slot in the range whose code has `bit` set (codes are sorted, the prefix above `bit` is shared).
    const uint32_t* first = code + (begin - base);
    mid = begin + (std::partition_point(first, first + n, [bit](uint32_t c) { return (c & bit) == 0; }) - first);
  }
  build_node(nodes, code, base, begin, mid, box_lo, box_hi, perm, leaf);
  const int64_t right = build_node(nodes, code, base, mid, end, box_lo, box_hi, perm, leaf);
  return finish_inner(nodes, node, begin, n, right);
}

// Stable Morton order of n points whose bounds are lo/hi: fills the sorted codes and the point index of each slot.
template <typename T>
void morton_sort(const T* pts, int64_t n, const T* lo, const T* hi, std::vector<uint32_t>& code,
                 std::vector<int64_t>& idx) {
  T inv[3];
  for (int k = 0; k < 3; ++k) inv[k] = hi[k] > lo[k] ? T(1023.99) / (hi[k] - lo[k]) : T(0);
  code.resize(n);
  idx.resize(n);
  at::parallel_for(0, n, GRAIN_LINEAR, [&](int64_t a, int64_t z) {
    for (int64_t i = a; i < z; ++i) {
      code[i] = morton(pts + 3 * i, lo, inv);
      idx[i] = i;
    }
  });
  radix_sort(code, idx);
}

// Per-column bounds of an (n, 3) array.
template <typename T>
void bounds3(const T* pts, int64_t n, T* lo, T* hi) {
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::numeric_limits<T>::infinity();
    hi[k] = -std::numeric_limits<T>::infinity();
  }
  for (int64_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], pts[3 * i + k]);
      hi[k] = std::max(hi[k], pts[3 * i + k]);
    }
}

// Morton order of query points (cache coherence of the traversal, seeding).
template <typename T>
std::vector<int64_t> query_order(const T* pts, int64_t n) {
  T lo[3], hi[3];
  bounds3(pts, n, lo, hi);
  std::vector<uint32_t> code;
  std::vector<int64_t> idx;
  morton_sort(pts, n, lo, hi, code, idx);
  return idx;
}

// Binned surface-area-heuristic build (for hierarchies that are kept and queried many times: a better tree than the
// Morton split for a few times its build cost). Node over the primitives idx[begin, end): SAH_BINS bins of the
// centroids along each axis, the split of least (left half-area x count + right half-area x count); object median
// when all centroids coincide or below SAH_MAX_DEPTH levels (bounds the depth, hence the traversal stack).
constexpr int SAH_BINS = 16;
constexpr int SAH_MAX_DEPTH = 48;

template <typename T>
inline T half_area(const T* lo, const T* hi) {
  const T dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
  return dx * dy + dy * dz + dz * dx;
}

template <typename T>
int64_t build_sah_node(std::vector<Node<T>>& nodes, int64_t* idx, int64_t begin, int64_t end, const T* box_lo,
                       const T* box_hi, const T* cen, int leaf, int depth) {
  const int64_t node = static_cast<int64_t>(nodes.size());
  nodes.emplace_back();
  const int64_t n = end - begin;
  constexpr T inf = std::numeric_limits<T>::infinity();
  T lo[3] = {inf, inf, inf}, hi[3] = {-inf, -inf, -inf}, clo[3] = {inf, inf, inf}, chi[3] = {-inf, -inf, -inf};
  for (int64_t i = begin; i < end; ++i) {
    const int64_t f = idx[i];
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], box_lo[3 * f + k]);
      hi[k] = std::max(hi[k], box_hi[3 * f + k]);
      clo[k] = std::min(clo[k], cen[3 * f + k]);
      chi[k] = std::max(chi[k], cen[3 * f + k]);
    }
  }
  if (n <= leaf) return set_leaf(nodes, node, begin, n, lo, hi);
  int best_axis = -1, best_split = 0;
  T best_cost = inf;
  if (depth < SAH_MAX_DEPTH) {
    for (int axis = 0; axis < 3; ++axis) {
      const T ext = chi[axis] - clo[axis];
      const T scale = T(SAH_BINS) / ext;
      if (!(ext > 0) || !std::isfinite(scale)) continue;  // flat axis (or so thin that the bin scale overflows)
      int64_t count[SAH_BINS] = {0};
      T blo[SAH_BINS][3], bhi[SAH_BINS][3];
      for (int b = 0; b < SAH_BINS; ++b)
        for (int k = 0; k < 3; ++k) {
          blo[b][k] = inf;
          bhi[b][k] = -inf;
        }
      for (int64_t i = begin; i < end; ++i) {
        const int64_t f = idx[i];
        const int b = std::min(SAH_BINS - 1, static_cast<int>((cen[3 * f + axis] - clo[axis]) * scale));
        ++count[b];
        for (int k = 0; k < 3; ++k) {
          blo[b][k] = std::min(blo[b][k], box_lo[3 * f + k]);
          bhi[b][k] = std::max(bhi[b][k], box_hi[3 * f + k]);
        }
      }
      T right_area[SAH_BINS];
      int64_t right_count[SAH_BINS];
      T rlo[3] = {inf, inf, inf}, rhi[3] = {-inf, -inf, -inf};
      int64_t rc = 0;
      for (int b = SAH_BINS - 1; b > 0; --b) {
        rc += count[b];
        for (int k = 0; k < 3; ++k) {
          rlo[k] = std::min(rlo[k], blo[b][k]);
          rhi[k] = std::max(rhi[k], bhi[b][k]);
        }
        right_area[b] = rc > 0 ? half_area(rlo, rhi) : T(0);
        right_count[b] = rc;
      }
      T llo[3] = {inf, inf, inf}, lhi[3] = {-inf, -inf, -inf};
      int64_t lc = 0;
      for (int b = 0; b < SAH_BINS - 1; ++b) {  // split between bin b and b + 1
        lc += count[b];
        for (int k = 0; k < 3; ++k) {
          llo[k] = std::min(llo[k], blo[b][k]);
          lhi[k] = std::max(lhi[k], bhi[b][k]);
        }
        if (lc == 0 || right_count[b + 1] == 0) continue;
        const T cost = half_area(llo, lhi) * T(lc) + right_area[b + 1] * T(right_count[b + 1]);
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = axis;
          best_split = b;
        }
      }
    }
  }
  int64_t mid = begin + n / 2;
  if (best_axis >= 0) {
    const T scale = T(SAH_BINS) / (chi[best_axis] - clo[best_axis]);
    const T c0 = clo[best_axis];
    const int split = best_split;
    const int axis = best_axis;
    mid = std::partition(idx + begin, idx + end,
                         [&](int64_t f) {
                           return std::min(SAH_BINS - 1, static_cast<int>((cen[3 * f + axis] - c0) * scale)) <= split;
                         }) -
          idx;
    if (mid == begin || mid == end) mid = begin + n / 2;
  }
  build_sah_node(nodes, idx, begin, mid, box_lo, box_hi, cen, leaf, depth + 1);
  const int64_t right = build_sah_node(nodes, idx, mid, end, box_lo, box_hi, cen, leaf, depth + 1);
  return finish_inner(nodes, node, begin, n, right);
}

// One SAH hierarchy per item; fills nodes, roots and perm like build_forest.
template <typename T>
void build_forest_sah(const T* box_lo, const T* box_hi, const T* cen, const int64_t* offsets, int64_t num_items,
                      int leaf, std::vector<Node<T>>& nodes, std::vector<int64_t>& roots, std::vector<int64_t>& perm) {
  const int64_t n = offsets[num_items];
  perm.resize(n);
  for (int64_t i = 0; i < n; ++i) perm[i] = i;
  roots.assign(num_items, -1);
  nodes.clear();
  nodes.reserve(2 * (n / leaf + num_items) + 1);
  for (int64_t b = 0; b < num_items; ++b) {
    const int64_t s = offsets[b], e = offsets[b + 1];
    if (e == s) continue;
    roots[b] = build_sah_node(nodes, perm.data(), s, e, box_lo, box_hi, cen, leaf, 0);
  }
}

// Builds one hierarchy per item (items: contiguous ranges [offsets[b], offsets[b+1]) of the primitives).
// Primitives are ordered along a Morton curve of their centroids within the item (LBVH-style ordering, Karras
// 2012), then split at the object median of that order. Fills the nodes (all items), the per-item roots (-1 for
// an empty item) and perm (global primitive index of each sorted slot).
template <typename T>
void build_forest(const T* box_lo, const T* box_hi, const T* cen, const int64_t* offsets, int64_t num_items,
                  int leaf, std::vector<Node<T>>& nodes, std::vector<int64_t>& roots, std::vector<int64_t>& perm) {
  const int64_t n = offsets[num_items];
  perm.resize(n);
  roots.assign(num_items, -1);
  nodes.clear();
  nodes.reserve(2 * (n / leaf + num_items) + 1);
  for (int64_t b = 0; b < num_items; ++b) {
    const int64_t s = offsets[b], e = offsets[b + 1];
    if (e == s) continue;
    T lo[3], hi[3];
    bounds3(cen + 3 * s, e - s, lo, hi);
    std::vector<uint32_t> code;
    std::vector<int64_t> idx;
    morton_sort(cen + 3 * s, e - s, lo, hi, code, idx);
    for (int64_t i = 0; i < e - s; ++i) perm[s + i] = s + idx[i];
    roots[b] = build_node(nodes, code.data(), s, s, e, box_lo, box_hi, perm.data(), leaf);  // code[i - s]: slot i
  }
}


template <typename T>
inline T box_sq_dist(const Node<T>& nd, const T* p) {
  T s = 0;
  for (int k = 0; k < 3; ++k) {
    T d = std::max(std::max(nd.lo[k] - p[k], T(0)), p[k] - nd.hi[k]);
    s += d * d;
  }
  return s;
}

// A node may hold a primitive whose *computed* squared distance equals the current best only if its box distance
// is below this bound: the computed distance deviates from the exact one by a few ulps of the coordinate scale
// (items are centred, |coordinates| <= scale) and of the distance itself. The slack keeps the pruning certified.
template <typename T>
inline T prune_bound(T best_sq, T slack_abs) {
  if (!(best_sq < std::numeric_limits<T>::infinity())) return best_sq;
  const T rel = T(64) * std::numeric_limits<T>::epsilon();
  const T d = std::sqrt(best_sq) * (T(1) + rel) + slack_abs;
  return d * d;
}

// Absolute pruning slack of an item whose largest |coordinate| is `scale` (items are centred): 64 ulps of it.
template <typename T>
inline T slack_of_scale(T scale) {
  return scale * (T(64) * std::numeric_limits<T>::epsilon());
}

// Per-item pruning slack (slack_of_scale) from the items' primitive boxes.
template <typename T>
std::vector<T> item_slack(const T* box_lo, const T* box_hi, const int64_t* offsets, int64_t num_items) {
  std::vector<T> scale(num_items, T(0));
  for (int64_t b = 0; b < num_items; ++b)
    for (int64_t i = offsets[b]; i < offsets[b + 1]; ++i)
      for (int k = 0; k < 3; ++k)
        scale[b] = std::max(scale[b], std::max(std::abs(box_lo[3 * i + k]), std::abs(box_hi[3 * i + k])));
  for (int64_t b = 0; b < num_items; ++b) scale[b] = slack_of_scale(scale[b]);
  return scale;
}

// Generic traversal: `leaf_fn(start, count, p, best_sq, best_idx)` updates the best candidate. Descends into the
// nearer child directly and stacks the farther one (if it can still hold a candidate); a stacked node is re-tested
// against the bound when popped, since the bound shrinks meanwhile.
template <typename T, typename LeafFn>
inline void traverse(const Node<T>* nodes, int64_t root, const T* p, T slack, T& best_sq, int64_t& best_idx,
                     LeafFn leaf_fn) {
  int64_t stack[128];
  T stack_d[128];
  int top = 0;
  T bound = prune_bound(best_sq, slack);
  if (box_sq_dist(nodes[root], p) > bound) return;
  int64_t ni = root;
  for (;;) {
    const Node<T>& nd = nodes[ni];
    if (nd.right < 0) {
      const T before = best_sq;
      leaf_fn(nd.start, nd.count, p, best_sq, best_idx);
      if (best_sq != before) bound = prune_bound(best_sq, slack);
    } else {
      const int64_t l = ni + 1, r = nd.right;
      const T dl = box_sq_dist(nodes[l], p), dr = box_sq_dist(nodes[r], p);
      const bool left_first = dl <= dr;
      const int64_t near = left_first ? l : r, far = left_first ? r : l;
      const T d_near = left_first ? dl : dr, d_far = left_first ? dr : dl;
      if (d_near <= bound) {
        if (d_far <= bound) {
          stack[top] = far;
          stack_d[top] = d_far;
          ++top;
        }
        ni = near;
        continue;
      }
    }
    // Next stacked node that can still hold a candidate, or done.
    for (;;) {
      if (top == 0) return;
      --top;
      if (stack_d[top] <= bound) {
        ni = stack[top];
        break;
      }
    }
  }
}

// Reference points of the hierarchies in sorted (slot) order, one array per coordinate, padded by LEAF_POINTS so
// that a leaf's LEAF_POINTS lanes can always be read: the leaf test computes all lanes in SIMD-friendly loops.
template <typename T>
struct SoaPoints {
  std::vector<T> x, y, z;
};

// `src(slot, k)` gives coordinate k of the point in `slot`.
template <typename T, typename Src>
SoaPoints<T> make_soa(int64_t n, Src src) {
  SoaPoints<T> s{std::vector<T>(n + LEAF_POINTS, T(0)), std::vector<T>(n + LEAF_POINTS, T(0)),
                 std::vector<T>(n + LEAF_POINTS, T(0))};
  at::parallel_for(0, n, GRAIN_LINEAR, [&](int64_t a, int64_t z) {
    for (int64_t i = a; i < z; ++i) {
      s.x[i] = src(i, 0);
      s.y[i] = src(i, 1);
      s.z[i] = src(i, 2);
    }
  });
  return s;
}

// Squared point distance in the order of the torch kernel's (d * d).sum(-1): ((dx*dx + dy*dy) + dz*dz).
template <typename T>
inline T soa_sq_dist(const T* xs, const T* ys, const T* zs, int64_t j, const T* p) {
  const T dx = p[0] - xs[j], dy = p[1] - ys[j], dz = p[2] - zs[j];
  T s = dx * dx;
  s += dy * dy;
  s += dz * dz;
  return s;
}

// Nearest reference point to p among the sorted points of one hierarchy; returns its slot. Selects by the computed
// squared distance ((dx*dx + dy*dy) + dz*dz, the torch kernel's order), lowest original index (perm[slot]) among
// equal squares, like the brute force. `seed` (a slot or -1) gives a first candidate, e.g. the previous
// Morton-adjacent query's answer: a tight starting bound, the answer is unchanged. `best_sq_out` receives the
// squared distance of the answer when not null.
template <typename T>
struct SoaView {
  const T* x;
  const T* y;
  const T* z;
};

template <typename T>
inline int64_t nearest_query(const Node<T>* nd, int64_t root, const T* p, T slack, const SoaView<T>& pts,
                             const int64_t* pm, int64_t seed, T* best_sq_out) {
  const T* xs = pts.x;
  const T* ys = pts.y;
  const T* zs = pts.z;
  T best = std::numeric_limits<T>::infinity();
  int64_t best_slot = -1;
  if (seed >= 0) {
    best = soa_sq_dist(xs, ys, zs, seed, p);
    best_slot = seed;
  }
  traverse<T>(nd, root, p, slack, best, best_slot,
              [xs, ys, zs, pm](int64_t start, int64_t count, const T* p, T& best_sq, int64_t& bs) {
                // All LEAF_POINTS lanes in straight-line loops (vectorised); lanes past `count` belong to the next
                // leaf, so the early exit (no lane at or below the best) tests a superset: it never skips a candidate.
                T sq[LEAF_POINTS];
                for (int l = 0; l < LEAF_POINTS; ++l) sq[l] = soa_sq_dist(xs + start, ys + start, zs + start, l, p);
                int any = 0;
                for (int l = 0; l < LEAF_POINTS; ++l) any |= static_cast<int>(sq[l] <= best_sq);
                if (bs >= 0 && !any) return;
                for (int64_t l = 0; l < count; ++l) {
                  const int64_t j = start + l;
                  if (bs < 0 || sq[l] < best_sq || (sq[l] == best_sq && pm[j] < pm[bs])) {
                    best_sq = sq[l];
                    bs = j;
                  }
                }
              });
  if (best_sq_out != nullptr) *best_sq_out = best;
  return best_slot;
}

// Kept hierarchies. A hierarchy lives in tensors so that Python owns it (MeshIndex). Points: the nodes as the raw
// bytes of a Node<T> array (torch allocations are 64-byte aligned), the per-item roots, the point of every sorted
// slot (perm), the points one array per coordinate in slot order and the per-item pruning slack. Faces: see the
// 4-wide layout below. `refit` rewrites bounds, primitive data and slack for moved vertices: same tree, same order.
template <typename T>
torch::Tensor nodes_tensor(const std::vector<Node<T>>& nodes) {
  auto t = torch::empty({static_cast<int64_t>(nodes.size() * sizeof(Node<T>))}, torch::dtype(torch::kUInt8));
  std::memcpy(t.data_ptr<uint8_t>(), nodes.data(), nodes.size() * sizeof(Node<T>));
  return t;
}

template <typename T>
Node<T>* nodes_of(const torch::Tensor& t) {
  return reinterpret_cast<Node<T>*>(t.data_ptr<uint8_t>());
}

template <typename T>
torch::Tensor vec_tensor(const std::vector<T>& v, torch::ScalarType st) {
  auto t = torch::empty({static_cast<int64_t>(v.size())}, torch::dtype(st));
  std::memcpy(t.data_ptr(), v.data(), v.size() * sizeof(T));
  return t;
}

// Face boxes (lo, hi) of face f.
template <typename T>
inline void face_box(const T* V, const int64_t* Fi, int64_t f, T* lo, T* hi) {
  const T* a = V + 3 * Fi[3 * f];
  const T* b = V + 3 * Fi[3 * f + 1];
  const T* c = V + 3 * Fi[3 * f + 2];
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::min(a[k], std::min(b[k], c[k]));
    hi[k] = std::max(a[k], std::max(b[k], c[k]));
  }
}

// Bottom-up bounds of a depth-first node array from per-slot boxes (children have larger indices than parents).
template <typename T>
void refit_nodes(Node<T>* nd, int64_t num_nodes, const T* slot_lo, const T* slot_hi) {
  for (int64_t i = num_nodes - 1; i >= 0; --i) {
    Node<T>& n = nd[i];
    if (n.right < 0) {
      for (int k = 0; k < 3; ++k) {
        n.lo[k] = std::numeric_limits<T>::infinity();
        n.hi[k] = -std::numeric_limits<T>::infinity();
      }
      for (int64_t s = n.start; s < n.start + n.count; ++s)
        for (int k = 0; k < 3; ++k) {
          n.lo[k] = std::min(n.lo[k], slot_lo[3 * s + k]);
          n.hi[k] = std::max(n.hi[k], slot_hi[3 * s + k]);
        }
    } else {
      union_children(nd, i);
    }
  }
}

// The parts of a kept hierarchy that every query reads (see the layout above).
template <typename T>
struct Kept {
  const Node<T>* nodes;
  const int64_t* roots;
  const int64_t* perm;
  const T* slack;
  explicit Kept(const std::vector<torch::Tensor>& h)
      : nodes(nodes_of<T>(h[0])),
        roots(h[1].data_ptr<int64_t>()),
        perm(h[2].data_ptr<int64_t>()),
        slack(h[4].data_ptr<T>()) {}
};

// Kept face hierarchy, 4-wide. The binary hierarchy (SAH or Morton) is collapsed into one whose nodes hold the boxes
// of up to WIDTH children, one array per axis and bound (the WIDTH box distances of a node are one vectorised pass;
// half the depth), and the faces of each leaf are stored as a block of WIDTH lanes, vertices by coordinate then lane
// (the WIDTH exact point-triangle distances are computed side by side). A leaf of fewer faces repeats its first face in
// the spare lanes: same distance, same face index, so the selection (lowest index among equal squares) is unchanged.
// Layout (tensors, so that Python owns the hierarchy): {nodes (WideNode bytes), roots (B,), block faces
// (blocks * WIDTH,), block data (blocks, sizeof(FaceBlock) / sizeof(T)), slack (B,)}.
constexpr int WIDTH = 4;
static_assert(WIDTH == LEAF_FACES, "the faces of a leaf fill one block");
// Traversal stack: a node pushes at most WIDTH entries and the stack holds at most WIDTH - 1 siblings per level of
// the current path; the binary depth (hence the wide depth) is below 128 (Morton: 30 code bits + object medians of
// equal codes, < 64 levels; SAH: SAH_MAX_DEPTH + object medians).
constexpr int WIDE_STACK = (WIDTH - 1) * 128 + WIDTH;

// Both records are cache-line aligned (torch allocations are 64-byte aligned): a node is two lines, a block three.
template <typename T>
struct alignas(64) WideNode {
  T lo[3][WIDTH];
  T hi[3][WIDTH];
  int32_t child[WIDTH];  // >= 0: a wide node; < 0: the face block ~child
  int32_t lanes;         // children in use: lanes [0, lanes)
};

// A block keeps the vertices of its faces and their indices (also in the hierarchy's block faces, read by the
// refit): the differences, normal and its square (FaceData) are recomputed in the leaf by face_data's own
// operations, the same values as stored ones, and three cache lines instead of five.
template <typename T>
struct alignas(64) FaceBlock {
  T a[3][WIDTH], b[3][WIDTH], c[3][WIDTH];
  int32_t face[WIDTH];
};

template <typename T>
inline void set_lane(FaceBlock<T>& blk, int l, const T* a, const T* b, const T* c, int64_t f) {
  for (int k = 0; k < 3; ++k) {
    blk.a[k][l] = a[k];
    blk.b[k][l] = b[k];
    blk.c[k][l] = c[k];
  }
  blk.face[l] = static_cast<int32_t>(f);
}

#if defined(__GNUC__)
// WIDTH lanes of T as one vector (GCC/Clang vector extensions): the block's faces and the node's boxes are measured
// side by side with tri_sq_dist / box_sq_dist's own operations (triangle.h).
template <typename T>
struct LaneVec;
template <>
struct LaneVec<float> {
  typedef float type __attribute__((vector_size(WIDTH * sizeof(float))));
};
template <>
struct LaneVec<double> {
  typedef double type __attribute__((vector_size(WIDTH * sizeof(double))));
};

template <typename T, typename V = typename LaneVec<T>::type>
inline V load_lanes(const T* x) {
  V v;
  std::memcpy(&v, x, sizeof(V));
  return v;
}

// Squared distances from p to the WIDTH faces of a block (tri_sq_dist, lane-wise).
template <typename T>
inline void block_sq_dists(const FaceBlock<T>& blk, const T* p, T* sq) {
  using V = typename LaneVec<T>::type;
  V a[3], b[3], c[3];
  for (int k = 0; k < 3; ++k) {
    a[k] = load_lanes(blk.a[k]);
    b[k] = load_lanes(blk.b[k]);
    c[k] = load_lanes(blk.c[k]);
  }
  const V pv[3] = {tmm::splat<V>(p[0]), tmm::splat<V>(p[1]), tmm::splat<V>(p[2])};
  const V d = tri_sq_dist(face_data(a, b, c), pv);
  std::memcpy(sq, &d, sizeof(V));
}

// Squared distances from p to the WIDTH child boxes of a node (box_sq_dist, lane-wise).
template <typename T>
inline void wide_box_dists(const WideNode<T>& nd, const T* p, T* d) {
  using V = typename LaneVec<T>::type;
  const V zero = tmm::splat<V>(0);
  V s = zero;
  for (int k = 0; k < 3; ++k) {
    const V pk = tmm::splat<V>(p[k]);
    const V g = tmm::vmax(tmm::vmax(load_lanes(nd.lo[k]) - pk, zero), pk - load_lanes(nd.hi[k]));
    s += g * g;
  }
  std::memcpy(d, &s, sizeof(V));
}
#else
template <typename T>
inline void block_sq_dists(const FaceBlock<T>& blk, const T* p, T* sq) {
  for (int l = 0; l < WIDTH; ++l) {
    T a[3], b[3], c[3];
    for (int k = 0; k < 3; ++k) {
      a[k] = blk.a[k][l];
      b[k] = blk.b[k][l];
      c[k] = blk.c[k][l];
    }
    sq[l] = tri_sq_dist(face_data(a, b, c), p);
  }
}

template <typename T>
inline void wide_box_dists(const WideNode<T>& nd, const T* p, T* d) {
  for (int l = 0; l < WIDTH; ++l) {
    T s = 0;
    for (int k = 0; k < 3; ++k) {
      const T g = std::max(std::max(nd.lo[k][l] - p[k], T(0)), p[k] - nd.hi[k][l]);
      s += g * g;
    }
    d[l] = s;
  }
}
#endif

// Wide node over the binary subtree at `n`: its children are the binary descendants obtained by opening the inner
// child of largest surface area until WIDTH are reached (the usual collapse). Nodes are allocated before their
// children (children have larger indices: the refit runs backwards). Returns the node index.
template <typename T>
int32_t collapse(const std::vector<Node<T>>& bin, int64_t n, const int64_t* perm, std::vector<WideNode<T>>& out,
                 std::vector<int64_t>& block_faces) {
  const int32_t me = static_cast<int32_t>(out.size());
  out.emplace_back();
  int64_t lane[WIDTH];
  int m = 0;
  if (bin[n].right < 0) {
    lane[m++] = n;
  } else {
    lane[m++] = n + 1;
    lane[m++] = bin[n].right;
    while (m < WIDTH) {
      int pick = -1;
      T most = -1;
      for (int l = 0; l < m; ++l) {
        const Node<T>& c = bin[lane[l]];
        if (c.right >= 0 && half_area(c.lo, c.hi) > most) {
          most = half_area(c.lo, c.hi);
          pick = l;
        }
      }
      if (pick < 0) break;
      const int64_t c = lane[pick];
      lane[pick] = c + 1;
      lane[m++] = bin[c].right;
    }
  }
  WideNode<T> w{};
  for (int l = 0; l < WIDTH; ++l) {
    for (int k = 0; k < 3; ++k) {  // an unused lane: an empty box (its distance is never read)
      w.lo[k][l] = std::numeric_limits<T>::infinity();
      w.hi[k][l] = -std::numeric_limits<T>::infinity();
    }
    w.child[l] = 0;
  }
  w.lanes = m;
  for (int l = 0; l < m; ++l) {
    const Node<T>& c = bin[lane[l]];
    if (c.right < 0) {
      const int64_t blk = static_cast<int64_t>(block_faces.size()) / WIDTH;
      for (int j = 0; j < WIDTH; ++j) block_faces.push_back(perm[c.start + (j < c.count ? j : 0)]);
      w.child[l] = ~static_cast<int32_t>(blk);
    } else {
      w.child[l] = collapse(bin, lane[l], perm, out, block_faces);
    }
  }
  out[me] = w;
  return me;
}

template <typename T>
WideNode<T>* wide_nodes_of(const torch::Tensor& t) {
  return reinterpret_cast<WideNode<T>*>(t.data_ptr<uint8_t>());
}

template <typename T>
FaceBlock<T>* blocks_of(const torch::Tensor& t) {
  return reinterpret_cast<FaceBlock<T>*>(t.data_ptr<T>());
}

// Face records and bounds of a kept face hierarchy from (moved) vertices, in place: every block's lanes (face data
// of its faces), every node's child boxes bottom up (a leaf lane: the union of its block's face boxes), and the
// per-item slack (slack_of_scale of the largest |coordinate| of the item, read from its root's boxes). Min and max are
// exact, so the boxes equal those of the binary build over the same faces.
template <typename T>
void fill_face_hierarchy(const std::vector<torch::Tensor>& h, const T* V, const int64_t* Fi) {
  WideNode<T>* nd = wide_nodes_of<T>(h[0]);
  const int64_t num_nodes = h[0].numel() / static_cast<int64_t>(sizeof(WideNode<T>));
  const int64_t* roots = h[1].data_ptr<int64_t>();
  const int64_t num_items = h[1].numel();
  const int64_t* bf = h[2].data_ptr<int64_t>();
  FaceBlock<T>* blk = blocks_of<T>(h[3]);
  const int64_t num_blocks = h[3].size(0);
  std::vector<T> blo(3 * num_blocks), bhi(3 * num_blocks);
  // ~1 us of work per block: a few thousand blocks pay for a parallel region.
  at::parallel_for(0, num_blocks, 2048, [&](int64_t s, int64_t e) {
    for (int64_t i = s; i < e; ++i) {
      T* lo = &blo[3 * i];
      T* hi = &bhi[3 * i];
      for (int l = 0; l < WIDTH; ++l) {
        const int64_t f = bf[WIDTH * i + l];
        set_lane(blk[i], l, V + 3 * Fi[3 * f], V + 3 * Fi[3 * f + 1], V + 3 * Fi[3 * f + 2], f);
        T flo[3], fhi[3];
        face_box(V, Fi, f, flo, fhi);
        for (int k = 0; k < 3; ++k) {
          lo[k] = l == 0 ? flo[k] : std::min(lo[k], flo[k]);
          hi[k] = l == 0 ? fhi[k] : std::max(hi[k], fhi[k]);
        }
      }
    }
  });
  for (int64_t i = num_nodes - 1; i >= 0; --i) {
    WideNode<T>& w = nd[i];
    for (int l = 0; l < w.lanes; ++l) {
      const int32_t c = w.child[l];
      if (c < 0) {
        for (int k = 0; k < 3; ++k) {
          w.lo[k][l] = blo[3 * int64_t(~c) + k];
          w.hi[k][l] = bhi[3 * int64_t(~c) + k];
        }
      } else {
        const WideNode<T>& cw = nd[c];
        for (int k = 0; k < 3; ++k) {
          T lo = cw.lo[k][0], hi = cw.hi[k][0];
          for (int j = 1; j < cw.lanes; ++j) {
            lo = std::min(lo, cw.lo[k][j]);
            hi = std::max(hi, cw.hi[k][j]);
          }
          w.lo[k][l] = lo;
          w.hi[k][l] = hi;
        }
      }
    }
  }
  T* slack = h[4].data_ptr<T>();
  for (int64_t b = 0; b < num_items; ++b) {
    T scale = 0;
    if (roots[b] >= 0) {
      const WideNode<T>& w = nd[roots[b]];
      for (int l = 0; l < w.lanes; ++l)
        for (int k = 0; k < 3; ++k) scale = std::max(scale, std::max(std::abs(w.lo[k][l]), std::abs(w.hi[k][l])));
    }
    slack[b] = slack_of_scale(scale);
  }
}

// Face hierarchy of centred verts (layout above).
template <typename T>
std::vector<torch::Tensor> face_bvh_build_impl(const torch::Tensor& verts, const torch::Tensor& faces,
                                               const torch::Tensor& face_offsets, bool sah) {
  const int64_t F = faces.size(0), B = face_offsets.size(0) - 1;
  TORCH_CHECK(F < (int64_t(1) << 30), "bvh: at most 2^30 faces per call, got ", F);
  const T* V = verts.data_ptr<T>();
  const int64_t* Fi = faces.data_ptr<int64_t>();
  const int64_t* off = face_offsets.data_ptr<int64_t>();
  std::vector<T> lo(3 * F), hi(3 * F), cen(3 * F);
  at::parallel_for(0, F, GRAIN_LINEAR, [&](int64_t s, int64_t e) {
    for (int64_t f = s; f < e; ++f) {
      face_box(V, Fi, f, &lo[3 * f], &hi[3 * f]);
      for (int k = 0; k < 3; ++k) cen[3 * f + k] = (lo[3 * f + k] + hi[3 * f + k]) * T(0.5);
    }
  });
  std::vector<Node<T>> bin;
  std::vector<int64_t> bin_roots, perm;
  if (sah)
    build_forest_sah<T>(lo.data(), hi.data(), cen.data(), off, B, LEAF_FACES, bin, bin_roots, perm);
  else
    build_forest<T>(lo.data(), hi.data(), cen.data(), off, B, LEAF_FACES, bin, bin_roots, perm);
  std::vector<WideNode<T>> wide;
  std::vector<int64_t> roots(B, -1), block_faces;
  wide.reserve(bin.size() / 2 + B + 1);
  block_faces.reserve(F + WIDTH * B);
  for (int64_t b = 0; b < B; ++b)
    if (bin_roots[b] >= 0) roots[b] = collapse(bin, bin_roots[b], perm.data(), wide, block_faces);
  auto nodes_t = torch::empty({static_cast<int64_t>(wide.size() * sizeof(WideNode<T>))}, torch::dtype(torch::kUInt8));
  std::memcpy(nodes_t.data_ptr<uint8_t>(), wide.data(), wide.size() * sizeof(WideNode<T>));
  const int64_t num_blocks = static_cast<int64_t>(block_faces.size()) / WIDTH;
  std::vector<torch::Tensor> h = {
      nodes_t, vec_tensor(roots, torch::kInt64), vec_tensor(block_faces, torch::kInt64),
      torch::zeros({num_blocks, static_cast<int64_t>(sizeof(FaceBlock<T>) / sizeof(T))}, verts.options()),
      torch::empty({B}, verts.options())};
  fill_face_hierarchy<T>(h, V, Fi);
  return h;
}

// Moved vertices, same faces: rewrites the face records, the bounds and the slack in place (same tree).
template <typename T>
void face_bvh_refit_impl(const std::vector<torch::Tensor>& h, const torch::Tensor& verts, const torch::Tensor& faces) {
  fill_face_hierarchy<T>(h, verts.data_ptr<T>(), faces.data_ptr<int64_t>());
}

// Tree quality of a kept face hierarchy: the summed half surface areas of every node's child boxes (the traversal
// cost the surface-area heuristic estimates) over those of the item roots' boxes (so that a uniform scaling or a rigid
// motion leaves it unchanged). A refit keeps the topology it was built with: after large deformations its boxes
// overlap and the ratio grows with the query time (docs/kernels.md), which is how MeshIndex decides to rebuild.
template <typename T>
double face_bvh_area_impl(const std::vector<torch::Tensor>& h) {
  const WideNode<T>* nd = wide_nodes_of<T>(h[0]);
  const int64_t num_nodes = h[0].numel() / static_cast<int64_t>(sizeof(WideNode<T>));
  const int64_t* roots = h[1].data_ptr<int64_t>();
  double total = 0, root_total = 0;
  auto lane_area = [](const WideNode<T>& w, int l) {
    const double lo[3] = {double(w.lo[0][l]), double(w.lo[1][l]), double(w.lo[2][l])};
    const double hi[3] = {double(w.hi[0][l]), double(w.hi[1][l]), double(w.hi[2][l])};
    return half_area(lo, hi);
  };
  for (int64_t i = 0; i < num_nodes; ++i)
    for (int l = 0; l < nd[i].lanes; ++l) total += lane_area(nd[i], l);
  for (int64_t b = 0; b < h[1].numel(); ++b) {
    if (roots[b] < 0) continue;
    const WideNode<T>& w = nd[roots[b]];
    double lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = double(w.lo[k][0]);
      hi[k] = double(w.hi[k][0]);
      for (int l = 1; l < w.lanes; ++l) {
        lo[k] = std::min(lo[k], double(w.lo[k][l]));
        hi[k] = std::max(hi[k], double(w.hi[k][l]));
      }
    }
    root_total += half_area(lo, hi);
  }
  return root_total > 0 ? total / root_total : 0.0;
}

// Closest face to p in one item's wide hierarchy: nearest child first (the children within the bound are stacked
// farthest first), a stacked entry re-tested against the bound when popped since the bound shrinks meanwhile.
template <typename T>
inline void wide_face_nearest(const WideNode<T>* nodes, const FaceBlock<T>* blocks, int32_t root, const T* p, T slack,
                              T& best_sq, int64_t& best_idx, int32_t& best_block, int& best_lane) {
  int32_t stack[WIDE_STACK];
  T stack_d[WIDE_STACK];
  int top = 0;
  T bound = prune_bound(best_sq, slack);
  int32_t c = root;  // the entry at hand and its box distance; the nearest child is taken directly, not stacked
  T dc = 0;
  for (;;) {
    if (dc <= bound) {
      if (c < 0) {
        T sq[WIDTH];
        block_sq_dists(blocks[~c], p, sq);
        T least = sq[0];
        for (int l = 1; l < WIDTH; ++l) least = std::min(least, sq[l]);
        if (least <= best_sq) {
          const int32_t* fs = blocks[~c].face;
          for (int l = 0; l < WIDTH; ++l)
            if (sq[l] < best_sq || (sq[l] == best_sq && fs[l] < best_idx)) {
              best_sq = sq[l];
              best_idx = fs[l];
              best_block = ~c;
              best_lane = l;
            }
          bound = prune_bound(best_sq, slack);
        }
      } else {
        const WideNode<T>& nd = nodes[c];
        T d[WIDTH];
        wide_box_dists(nd, p, d);
        int order[WIDTH];
        int m = 0;
        for (int l = 0; l < nd.lanes; ++l) {
          if (!(d[l] <= bound)) continue;
          int j = m++;
          for (; j > 0 && d[order[j - 1]] < d[l]; --j) order[j] = order[j - 1];  // farthest first
          order[j] = l;
        }
        if (m > 0) {
          for (int j = 0; j < m - 1; ++j) {
            stack[top] = nd.child[order[j]];
            stack_d[top] = d[order[j]];
            ++top;
          }
          c = nd.child[order[m - 1]];
          dc = d[order[m - 1]];
          continue;
        }
      }
    }
    if (top == 0) return;
    --top;
    c = stack[top];
    dc = stack_d[top];
  }
}

// One int64 answer per query point: `fn(begin, end, order, out)` answers the queries order[begin, end) (Morton
// order, chunks scheduled by chunked_for) into out.
template <typename T, typename F>
torch::Tensor query_in_morton_order(const torch::Tensor& points, const F& fn) {
  const int64_t P = points.size(0);
  auto out = torch::empty({P}, torch::dtype(torch::kInt64));
  int64_t* o = out.data_ptr<int64_t>();
  const std::vector<int64_t> order = query_order<T>(points.data_ptr<T>(), P);
  const int64_t* ord = order.data();
  chunked_for(P, QUERY_CHUNK, [&](int64_t s, int64_t e) { fn(s, e, ord, o); });
  return out;
}

// Closest face per centred query point through a kept face hierarchy (lowest face index among equal squares).
// With `closest`, also the closest point on that face as closest_points computes it ({face_idx, sq_dists, bary,
// closest}), from the vertices in the winning block, which the traversal has just read; without, {face_idx}.
template <typename T>
std::vector<torch::Tensor> face_bvh_query_impl(const std::vector<torch::Tensor>& h, const torch::Tensor& points,
                                               const torch::Tensor& point_batch, const torch::Tensor& face_offsets,
                                               bool closest) {
  const WideNode<T>* nd = wide_nodes_of<T>(h[0]);
  const int64_t* roots = h[1].data_ptr<int64_t>();
  const FaceBlock<T>* blk = blocks_of<T>(h[3]);
  const T* slack = h[4].data_ptr<T>();
  const int64_t* off = face_offsets.data_ptr<int64_t>();
  const T* Pp = points.data_ptr<T>();
  const int64_t* pb = point_batch.data_ptr<int64_t>();
  const int64_t P = points.size(0);
  std::vector<torch::Tensor> out(1);
  T *sq = nullptr, *bary = nullptr, *cl = nullptr;
  if (closest) {
    out.push_back(torch::empty({P}, points.options()));
    out.push_back(torch::empty({P, 3}, points.options()));
    out.push_back(torch::empty({P, 3}, points.options()));
    sq = out[1].data_ptr<T>();
    bary = out[2].data_ptr<T>();
    cl = out[3].data_ptr<T>();
  }
  out[0] = query_in_morton_order<T>(points, [&](int64_t s, int64_t e, const int64_t* ord, int64_t* o) {
    for (int64_t q = s; q < e; ++q) {
      const int64_t i = ord[q];
      const int64_t b = pb[i];
      const T* p = Pp + 3 * i;
      T best = std::numeric_limits<T>::infinity();
      int64_t best_idx = off[b];
      int32_t best_block = -1;
      int best_lane = 0;
      // No seeding here (unlike nearest points): nearest-child-first descent to a 4-face leaf finds a tight bound at
      // once, and evaluating the predecessor's face first measured 5-10% slower.
      if (roots[b] >= 0)
        wide_face_nearest<T>(nd, blk, static_cast<int32_t>(roots[b]), p, slack[b], best, best_idx, best_block,
                             best_lane);
      o[i] = best_idx;
      if (closest && best_block < 0) {  // an item without faces (callers reject its points before)
        sq[i] = std::numeric_limits<T>::infinity();
        for (int k = 0; k < 3; ++k) bary[3 * i + k] = cl[3 * i + k] = T(0);
      } else if (closest) {
        const FaceBlock<T>& w = blk[best_block];
        const T a[3] = {w.a[0][best_lane], w.a[1][best_lane], w.a[2][best_lane]};
        const T bb[3] = {w.b[0][best_lane], w.b[1][best_lane], w.b[2][best_lane]};
        const T c[3] = {w.c[0][best_lane], w.c[1][best_lane], w.c[2][best_lane]};
        sq[i] = closest_on_face(a, bb, c, p, bary + 3 * i, cl + 3 * i);
      }
    }
  });
  return out;
}

// Point hierarchy of centred reference points: {nodes, roots, perm, points (3, R + LEAF_POINTS) by coordinate in
// slot order, slack (B,)}.
template <typename T>
std::vector<torch::Tensor> point_bvh_build_impl(const torch::Tensor& ref, const torch::Tensor& ref_offsets) {
  const int64_t R = ref.size(0), B = ref_offsets.size(0) - 1;
  const T* Rp = ref.data_ptr<T>();
  const int64_t* off = ref_offsets.data_ptr<int64_t>();
  std::vector<Node<T>> nodes;
  std::vector<int64_t> roots, perm;
  build_forest<T>(Rp, Rp, Rp, off, B, LEAF_POINTS, nodes, roots, perm);
  auto soa = torch::zeros({3, R + LEAF_POINTS}, ref.options());
  T* s = soa.data_ptr<T>();
  const int64_t stride = R + LEAF_POINTS;
  for (int64_t i = 0; i < R; ++i)
    for (int k = 0; k < 3; ++k) s[k * stride + i] = Rp[3 * perm[i] + k];
  const std::vector<T> slack = item_slack<T>(Rp, Rp, off, B);
  return {nodes_tensor(nodes), vec_tensor(roots, torch::kInt64), vec_tensor(perm, torch::kInt64), soa,
          vec_tensor(slack, ref.scalar_type())};
}

template <typename T>
void point_bvh_refit_impl(const std::vector<torch::Tensor>& h, const torch::Tensor& ref,
                          const torch::Tensor& ref_offsets) {
  const int64_t R = ref.size(0), B = ref_offsets.size(0) - 1;
  const T* Rp = ref.data_ptr<T>();
  const int64_t* perm = h[2].data_ptr<int64_t>();
  T* s = h[3].data_ptr<T>();
  const int64_t stride = R + LEAF_POINTS;
  std::vector<T> sorted(3 * R);
  for (int64_t i = 0; i < R; ++i)
    for (int k = 0; k < 3; ++k) {
      const T v = Rp[3 * perm[i] + k];
      s[k * stride + i] = v;
      sorted[3 * i + k] = v;
    }
  refit_nodes(nodes_of<T>(h[0]), h[0].numel() / static_cast<int64_t>(sizeof(Node<T>)), sorted.data(),
              sorted.data());
  const std::vector<T> slack = item_slack<T>(Rp, Rp, ref_offsets.data_ptr<int64_t>(), B);
  std::memcpy(h[4].data_ptr<T>(), slack.data(), B * sizeof(T));
}

// Tree quality of a kept point hierarchy, as face_bvh_area_impl: the summed half areas of all its nodes' boxes over
// those of the item roots.
template <typename T>
double point_bvh_area_impl(const std::vector<torch::Tensor>& h) {
  const Node<T>* nd = nodes_of<T>(h[0]);
  const int64_t num_nodes = h[0].numel() / static_cast<int64_t>(sizeof(Node<T>));
  const int64_t* roots = h[1].data_ptr<int64_t>();
  auto area = [](const Node<T>& n) {
    const double lo[3] = {double(n.lo[0]), double(n.lo[1]), double(n.lo[2])};
    const double hi[3] = {double(n.hi[0]), double(n.hi[1]), double(n.hi[2])};
    return half_area(lo, hi);
  };
  double total = 0, root_total = 0;
  for (int64_t i = 0; i < num_nodes; ++i) total += area(nd[i]);
  for (int64_t b = 0; b < h[1].numel(); ++b)
    if (roots[b] >= 0) root_total += area(nd[roots[b]]);
  return root_total > 0 ? total / root_total : 0.0;
}

// Nearest reference point per centred query point through a kept point hierarchy, see nearest_query.
template <typename T>
torch::Tensor point_bvh_query_impl(const std::vector<torch::Tensor>& h, const torch::Tensor& points,
                                   const torch::Tensor& point_batch) {
  const Kept<T> kh(h);
  const int64_t stride = h[3].size(1);
  const T* s = h[3].data_ptr<T>();
  const SoaView<T> rs{s, s + stride, s + 2 * stride};
  const T* Pp = points.data_ptr<T>();
  const int64_t* pb = point_batch.data_ptr<int64_t>();
  const int64_t* pm = kh.perm;
  return query_in_morton_order<T>(points, [&](int64_t s0, int64_t e, const int64_t* ord, int64_t* o) {
    int64_t prev_item = -1, prev_slot = -1;
    for (int64_t q = s0; q < e; ++q) {
      const int64_t i = ord[q];
      const int64_t b = pb[i];
      const int64_t slot = nearest_query<T>(kh.nodes, kh.roots[b], Pp + 3 * i, kh.slack[b], rs, pm,
                                            b == prev_item ? prev_slot : -1, nullptr);
      o[i] = pm[slot];
      prev_item = b;
      prev_slot = slot;
    }
  });
}

// Per-column bounds of an (n, 3) array and whether every value is finite, in one pass (per-thread blocks above
// GRAIN_LINEAR rows; min and max are exact, so the result does not depend on the split).
template <typename T>
bool bounds_finite(const T* x, int64_t n, T* lo, T* hi) {
  const int64_t blocks = n < GRAIN_LINEAR ? 1 : std::max<int64_t>(1, std::min<int64_t>(at::get_num_threads(), 64));
  std::vector<T> part(6 * blocks);
  std::vector<char> ok(blocks, 1);
  auto run = [&](int64_t b) {
    T l[3], h[3];
    for (int k = 0; k < 3; ++k) {
      l[k] = std::numeric_limits<T>::infinity();
      h[k] = -std::numeric_limits<T>::infinity();
    }
    bool finite = true;
    for (int64_t i = n * b / blocks; i < n * (b + 1) / blocks; ++i)
      for (int k = 0; k < 3; ++k) {
        const T v = x[3 * i + k];
        finite &= std::isfinite(v);
        l[k] = std::min(l[k], v);
        h[k] = std::max(h[k], v);
      }
    for (int k = 0; k < 3; ++k) {
      part[6 * b + k] = l[k];
      part[6 * b + 3 + k] = h[k];
    }
    ok[b] = finite;
  };
  if (blocks == 1)
    run(0);
  else
    at::parallel_for(0, blocks, 1, [&](int64_t b0, int64_t b1) {
      for (int64_t b = b0; b < b1; ++b) run(b);
    });
  bool finite = true;
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::numeric_limits<T>::infinity();
    hi[k] = -std::numeric_limits<T>::infinity();
  }
  for (int64_t b = 0; b < blocks; ++b) {
    finite &= ok[b] != 0;
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], part[6 * b + k]);
      hi[k] = std::max(hi[k], part[6 * b + 3 + k]);
    }
  }
  return finite;
}

// Batch-of-one nearest reference point, fused: finiteness check, bounding-box centring (the same operations as
// kernels._common.item_centers and `x - center`), Morton sort and build on the centred reference, seeded queries in
// Morton order, and the distances. Returns {} when a value is not finite (the caller raises the typed error), else
// {sq_dists (P,) = squared distance computed as (p - c) - (r - c) summed in order x, y, z (bit-identical to the
// torch recomputation; the caller takes torch.sqrt, whose float32 rounding differs from std::sqrt's on this
// build), idx (P,) int64, center (3,)}.
template <typename T>
std::vector<torch::Tensor> nearest_single_impl(const torch::Tensor& points, const torch::Tensor& ref) {
  const int64_t R = ref.size(0), P = points.size(0);
  const T* Rp = ref.data_ptr<T>();
  const T* Pp = points.data_ptr<T>();
  T lo[3], hi[3], plo[3], phi[3];
  if (!bounds_finite(Rp, R, lo, hi) || !bounds_finite(Pp, P, plo, phi)) return {};
  auto center = torch::empty({3}, ref.options());
  T* c = center.data_ptr<T>();
  T scale = 0;
  for (int k = 0; k < 3; ++k) {
    c[k] = T(0.5) * (lo[k] + hi[k]);
    // Rounding is monotone, so the extremes of the centred values are the centred extremes.
    scale = std::max(scale, std::max(std::abs(lo[k] - c[k]), std::abs(hi[k] - c[k])));
  }
  const T slack = slack_of_scale(scale);
  std::vector<uint32_t> code;
  std::vector<int64_t> perm;
  morton_sort(Rp, R, lo, hi, code, perm);
  const int64_t* pm = perm.data();
  std::vector<T> rs(3 * R);  // centred reference points in sorted order
  at::parallel_for(0, R, GRAIN_LINEAR, [&](int64_t a, int64_t z) {
    for (int64_t i = a; i < z; ++i)
      for (int k = 0; k < 3; ++k) rs[3 * i + k] = Rp[3 * pm[i] + k] - c[k];
  });
  std::vector<Node<T>> nodes;
  nodes.reserve(2 * (R / LEAF_POINTS + 1) + 1);
  build_node<T>(nodes, code.data(), 0, 0, R, rs.data(), rs.data(), nullptr, LEAF_POINTS);
  const SoaPoints<T> soa = make_soa<T>(R, [&rs](int64_t i, int k) { return rs[3 * i + k]; });
  const SoaView<T> sv{soa.x.data(), soa.y.data(), soa.z.data()};
  auto sq_dists = torch::empty({P}, points.options());
  auto idx = torch::empty({P}, torch::dtype(torch::kInt64));
  T* dp = sq_dists.data_ptr<T>();
  int64_t* o = idx.data_ptr<int64_t>();
  const Node<T>* nd = nodes.data();
  const std::vector<int64_t> order = query_order<T>(Pp, P);
  const int64_t* ord = order.data();
  chunked_for(P, QUERY_CHUNK, [&](int64_t s, int64_t e) {
    int64_t prev_slot = -1;
    for (int64_t q = s; q < e; ++q) {
      const int64_t i = ord[q];
      const T pc[3] = {Pp[3 * i] - c[0], Pp[3 * i + 1] - c[1], Pp[3 * i + 2] - c[2]};
      T best_sq;
      const int64_t slot = nearest_query<T>(nd, 0, pc, slack, sv, pm, prev_slot, &best_sq);
      o[i] = pm[slot];
      dp[i] = best_sq;
      prev_slot = slot;
    }
  });
  return {sq_dists, idx, center};
}

// Closest point on the selected face of every point, without autograd: the operations of the torch functions
// kernels/triangle.py region_candidates and closest_point_on_triangle, in their order and dtype (no FMA), so that
// the results are bit-identical to the differentiable recomputation. Inputs are centred; faces index verts.
// Returns {sq_dists (P,), bary (P, 3), closest (P, 3)} (closest in the centred frame).
template <typename T>
std::vector<torch::Tensor> closest_points_impl(const torch::Tensor& points, const torch::Tensor& verts,
                                               const torch::Tensor& faces, const torch::Tensor& face_idx) {
  const int64_t P = points.size(0);
  const T* Pp = points.data_ptr<T>();
  const T* V = verts.data_ptr<T>();
  const int64_t* Fi = faces.data_ptr<int64_t>();
  const int64_t* sel = face_idx.data_ptr<int64_t>();
  auto sq_out = torch::empty({P}, points.options());
  auto bary_out = torch::empty({P, 3}, points.options());
  auto closest_out = torch::empty({P, 3}, points.options());
  T* sq_p = sq_out.data_ptr<T>();
  T* bary_p = bary_out.data_ptr<T>();
  T* cl_p = closest_out.data_ptr<T>();
  at::parallel_for(0, P, 2048, [&](int64_t s0, int64_t s1) {
    for (int64_t i = s0; i < s1; ++i) {
      const int64_t f = sel[i];
      const T* a = V + 3 * Fi[3 * f];
      const T* b = V + 3 * Fi[3 * f + 1];
      const T* c = V + 3 * Fi[3 * f + 2];
      const T* p = Pp + 3 * i;
      sq_p[i] = closest_on_face(a, b, c, p, bary_p + 3 * i, cl_p + 3 * i);
    }
  });
  return {sq_out, bary_out, closest_out};
}

// k nearest reference points with MPEG mmetric's arithmetic (mpeg-pcc-dmetric's k-d tree distance): float32
// coordinate differences, their squares summed in double as (dx*dx + dy*dy) + dz*dz. Candidates are ranked by
// (squared distance, reference index), so exact ties are kept in index order and never dropped below rank k.
constexpr int LEAF_KNN = 8;
constexpr int MAX_KNN = 64;

inline double mpeg_sq(const float* q, float rx, float ry, float rz) {
  const double dx = static_cast<double>(q[0] - rx);
  const double dy = static_cast<double>(q[1] - ry);
  const double dz = static_cast<double>(q[2] - rz);
  double s = dx * dx + dy * dy;
  s += dz * dz;
  return s;
}

// Lower bound of mpeg_sq over a box: per axis the gap to the box in double. The float32 difference of a point in the
// box can round below the exact gap by a relative 2^-24, so the caller widens its bound by a relative 1e-6.
inline double box_gap_sq(const Node<float>& nd, const float* q) {
  double s = 0;
  for (int k = 0; k < 3; ++k) {
    const double d = std::max({static_cast<double>(nd.lo[k]) - q[k], static_cast<double>(q[k]) - nd.hi[k], 0.0});
    s += d * d;
  }
  return s;
}

struct KnnList {
  int k;
  int n = 0;
  double sq[MAX_KNN];
  int64_t idx[MAX_KNN];
  // Pruning bound: a box whose gap exceeds it cannot hold a candidate that ranks in the list.
  double bound() const { return n < k ? std::numeric_limits<double>::infinity() : sq[k - 1] * (1.0 + 1e-6); }
  void offer(double s, int64_t i) {
    if (n == k && (s > sq[k - 1] || (s == sq[k - 1] && i >= idx[k - 1]))) return;
    for (int j = 0; j < n; ++j)
      if (idx[j] == i) return;  // a seed met again in the traversal
    int j = n < k ? n++ : k - 1;
    while (j > 0 && (sq[j - 1] > s || (sq[j - 1] == s && idx[j - 1] > i))) {
      sq[j] = sq[j - 1];
      idx[j] = idx[j - 1];
      --j;
    }
    sq[j] = s;
    idx[j] = i;
  }
};

std::vector<torch::Tensor> mpeg_knn_impl(const torch::Tensor& query, const torch::Tensor& ref, int k) {
  const int64_t Q = query.size(0), R = ref.size(0);
  const float* Qp = query.data_ptr<float>();
  const float* Rp = ref.data_ptr<float>();
  const int64_t off[2] = {0, R};
  std::vector<Node<float>> nodes;
  std::vector<int64_t> roots, perm;
  build_forest<float>(Rp, Rp, Rp, off, 1, LEAF_KNN, nodes, roots, perm);
  std::vector<float> soa(3 * (R + LEAF_KNN), 0.0f);  // slot order, one array per coordinate, padded for whole leaves
  float* xs = soa.data();
  float* ys = xs + R + LEAF_KNN;
  float* zs = ys + R + LEAF_KNN;
  for (int64_t i = 0; i < R; ++i) {
    xs[i] = Rp[3 * perm[i]];
    ys[i] = Rp[3 * perm[i] + 1];
    zs[i] = Rp[3 * perm[i] + 2];
  }
  auto idx_out = torch::full({Q, k}, -1, torch::dtype(torch::kInt64));
  auto sq_out = torch::full({Q, k}, std::numeric_limits<double>::infinity(), torch::dtype(torch::kFloat64));
  int64_t* io = idx_out.data_ptr<int64_t>();
  double* so = sq_out.data_ptr<double>();
  const std::vector<int64_t> order = query_order<float>(Qp, Q);
  const Node<float>* nd = nodes.data();
  const int64_t* pm = perm.data();
  chunked_for(Q, QUERY_CHUNK, [&](int64_t s0, int64_t e) {
    KnnList prev{k};  // the previous (Morton-adjacent) query's answers: a tight first bound
    for (int64_t q = s0; q < e; ++q) {
      const int64_t i = order[q];
      const float* p = Qp + 3 * i;
      KnnList best{k};
      for (int a = 0; a < prev.n; ++a) {
        const float* r = Rp + 3 * prev.idx[a];
        best.offer(mpeg_sq(p, r[0], r[1], r[2]), prev.idx[a]);
      }
      double bound = best.bound();
      int64_t stack[128];
      double stack_d[128];
      int top = 0;
      int64_t ni = roots[0];
      double dn = box_gap_sq(nd[ni], p);
      for (;;) {
        if (dn <= bound) {
          const Node<float>& node = nd[ni];
          if (node.right < 0) {
            // every lane of the leaf in a straight-line loop (vectorised); lanes past `count` are not offered
            double sq[LEAF_KNN];
            for (int l = 0; l < LEAF_KNN; ++l) {
              const int64_t j = node.start + l;
              sq[l] = mpeg_sq(p, xs[j], ys[j], zs[j]);
            }
            const double keep = best.n < k ? std::numeric_limits<double>::infinity() : best.sq[k - 1];
            for (int64_t l = 0; l < node.count; ++l)
              if (sq[l] <= keep) best.offer(sq[l], pm[node.start + l]);
            bound = best.bound();
          } else {
            const int64_t l = ni + 1, r = node.right;
            const double dl = box_gap_sq(nd[l], p), dr = box_gap_sq(nd[r], p);
            const bool left_first = dl <= dr;
            stack[top] = left_first ? r : l;
            stack_d[top] = left_first ? dr : dl;
            ++top;
            ni = left_first ? l : r;
            dn = left_first ? dl : dr;
            continue;
          }
        }
        if (top == 0) break;
        --top;
        ni = stack[top];
        dn = stack_d[top];
      }
      for (int a = 0; a < best.n; ++a) {
        io[i * k + a] = best.idx[a];
        so[i * k + a] = best.sq[a];
      }
      prev = best;
    }
  });
  return {idx_out, sq_out};
}

void check_inputs(const torch::Tensor& points, const torch::Tensor& point_batch, const torch::Tensor& prims,
                  const torch::Tensor& offsets) {
  TORCH_CHECK(points.device().is_cpu() && prims.device().is_cpu(), "bvh: CPU tensors expected");
  TORCH_CHECK(points.is_contiguous() && prims.is_contiguous(), "bvh: contiguous tensors expected");
  TORCH_CHECK(point_batch.scalar_type() == torch::kInt64 && offsets.scalar_type() == torch::kInt64,
              "bvh: int64 batch/offsets expected");
  TORCH_CHECK(point_batch.is_contiguous() && offsets.is_contiguous(), "bvh: contiguous batch/offsets expected");
}

}  // namespace

#define TMM_DISPATCH(dtype, call)                                     \
  do {                                                                \
    if ((dtype) == torch::kFloat64) { using T = double; call; }       \
    TORCH_CHECK((dtype) == torch::kFloat32, "bvh: float32 or float64 expected"); \
    { using T = float; call; }                                        \
  } while (0)

std::vector<torch::Tensor> face_bvh_build(torch::Tensor verts, torch::Tensor faces, torch::Tensor face_offsets,
                                          bool sah) {
  check_inputs(verts, face_offsets, verts, face_offsets);
  TORCH_CHECK(faces.scalar_type() == torch::kInt64 && faces.is_contiguous(), "bvh: contiguous int64 faces expected");
  TMM_DISPATCH(verts.scalar_type(), return face_bvh_build_impl<T>(verts, faces, face_offsets, sah));
}

void face_bvh_refit(std::vector<torch::Tensor> h, torch::Tensor verts, torch::Tensor faces,
                    torch::Tensor face_offsets) {
  check_inputs(verts, face_offsets, verts, face_offsets);
  TORCH_CHECK(h.size() == 5 && h[3].scalar_type() == verts.scalar_type(), "bvh: hierarchy of another dtype");
  TMM_DISPATCH(verts.scalar_type(), return face_bvh_refit_impl<T>(h, verts, faces));
}

std::vector<torch::Tensor> face_bvh_query(std::vector<torch::Tensor> h, torch::Tensor points, torch::Tensor point_batch,
                                          torch::Tensor face_offsets, bool closest) {
  check_inputs(points, point_batch, h[3], face_offsets);
  TORCH_CHECK(h.size() == 5 && h[3].scalar_type() == points.scalar_type(), "bvh: points and hierarchy dtypes differ");
  TMM_DISPATCH(points.scalar_type(), return face_bvh_query_impl<T>(h, points, point_batch, face_offsets, closest));
}

double face_bvh_area(std::vector<torch::Tensor> h) {
  TORCH_CHECK(h.size() == 5, "bvh: a face hierarchy expected");
  TMM_DISPATCH(h[3].scalar_type(), return face_bvh_area_impl<T>(h));
}

double point_bvh_area(std::vector<torch::Tensor> h) {
  TORCH_CHECK(h.size() == 5, "bvh: a point hierarchy expected");
  TMM_DISPATCH(h[3].scalar_type(), return point_bvh_area_impl<T>(h));
}

std::vector<torch::Tensor> point_bvh_build(torch::Tensor ref, torch::Tensor ref_offsets) {
  check_inputs(ref, ref_offsets, ref, ref_offsets);
  TMM_DISPATCH(ref.scalar_type(), return point_bvh_build_impl<T>(ref, ref_offsets));
}

void point_bvh_refit(std::vector<torch::Tensor> h, torch::Tensor ref, torch::Tensor ref_offsets) {
  check_inputs(ref, ref_offsets, ref, ref_offsets);
  TORCH_CHECK(h.size() == 5 && h[3].scalar_type() == ref.scalar_type(), "bvh: hierarchy of another dtype");
  TMM_DISPATCH(ref.scalar_type(), return point_bvh_refit_impl<T>(h, ref, ref_offsets));
}

torch::Tensor point_bvh_query(std::vector<torch::Tensor> h, torch::Tensor points, torch::Tensor point_batch) {
  check_inputs(points, point_batch, h[3], h[1]);
  TORCH_CHECK(h.size() == 5 && h[3].scalar_type() == points.scalar_type(), "bvh: points and hierarchy dtypes differ");
  TMM_DISPATCH(points.scalar_type(), return point_bvh_query_impl<T>(h, points, point_batch));
}

std::vector<torch::Tensor> nearest_single(torch::Tensor points, torch::Tensor ref) {
  TORCH_CHECK(points.device().is_cpu() && ref.device().is_cpu(), "bvh: CPU tensors expected");
  TORCH_CHECK(points.is_contiguous() && ref.is_contiguous(), "bvh: contiguous tensors expected");
  TORCH_CHECK(points.scalar_type() == ref.scalar_type(), "bvh: points and ref must share a dtype");
  TORCH_CHECK(points.size(0) > 0 && ref.size(0) > 0, "bvh: non-empty points and ref expected");
  if (points.scalar_type() == torch::kFloat64) return nearest_single_impl<double>(points, ref);
  TORCH_CHECK(points.scalar_type() == torch::kFloat32, "bvh: float32 or float64 expected");
  return nearest_single_impl<float>(points, ref);
}

std::vector<torch::Tensor> closest_points(torch::Tensor points, torch::Tensor verts, torch::Tensor faces,
                                          torch::Tensor face_idx) {
  TORCH_CHECK(points.device().is_cpu() && verts.device().is_cpu(), "bvh: CPU tensors expected");
  TORCH_CHECK(points.is_contiguous() && verts.is_contiguous(), "bvh: contiguous tensors expected");
  TORCH_CHECK(faces.scalar_type() == torch::kInt64 && faces.is_contiguous(), "bvh: contiguous int64 faces expected");
  TORCH_CHECK(face_idx.scalar_type() == torch::kInt64 && face_idx.is_contiguous(),
              "bvh: contiguous int64 face_idx expected");
  TORCH_CHECK(points.scalar_type() == verts.scalar_type(), "bvh: points and verts must share a dtype");
  if (points.scalar_type() == torch::kFloat64) return closest_points_impl<double>(points, verts, faces, face_idx);
  TORCH_CHECK(points.scalar_type() == torch::kFloat32, "bvh: float32 or float64 expected");
  return closest_points_impl<float>(points, verts, faces, face_idx);
}

std::vector<torch::Tensor> mpeg_knn(torch::Tensor query, torch::Tensor ref, int64_t k) {
  TORCH_CHECK(query.device().is_cpu() && ref.device().is_cpu(), "mpeg_knn: CPU tensors expected");
  TORCH_CHECK(query.is_contiguous() && ref.is_contiguous(), "mpeg_knn: contiguous tensors expected");
  TORCH_CHECK(query.scalar_type() == torch::kFloat32 && ref.scalar_type() == torch::kFloat32,
              "mpeg_knn: float32 points expected");
  TORCH_CHECK(ref.size(0) > 0, "mpeg_knn: non-empty reference expected");
  TORCH_CHECK(k >= 1 && k <= MAX_KNN, "mpeg_knn: k out of range");
  return mpeg_knn_impl(query, ref, static_cast<int>(k));
}

// deformation_energy.cpp (compiled into the same extension).
torch::Tensor deform_vertices(torch::Tensor R, torch::Tensor t, torch::Tensor g, torch::Tensor rest,
                              torch::Tensor vidx, torch::Tensor vw);
torch::Tensor farthest_point_sampling(torch::Tensor points, int64_t start, double spacing2);

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("deform_vertices", &deform_vertices, "Embedded deformation of skinned vertices (no gradient)");
  m.def("farthest_point_sampling", &farthest_point_sampling, "Farthest-point sampling to a covering radius");
  m.def("face_bvh_build", &face_bvh_build,
        "Kept 4-wide face hierarchy (Morton split, or binned SAH, collapsed): [nodes, roots, block faces, blocks, "
        "slack]");
  m.def("face_bvh_refit", &face_bvh_refit, "Refit a kept face hierarchy to moved vertices (in place)");
  m.def("face_bvh_query", &face_bvh_query,
        "Closest face per point (kept hierarchy, exact, lowest index on ties): {face_idx}, or with closest=True "
        "{face_idx, sq_dists, bary, closest} as closest_points, in the same pass");
  m.def("face_bvh_area", &face_bvh_area,
        "Tree quality of a kept face hierarchy: summed half areas of the node boxes over the roots' (SAH cost)");
  m.def("point_bvh_area", &point_bvh_area,
        "Tree quality of a kept point hierarchy: summed half areas of the node boxes over the roots' (SAH cost)");
  m.def("point_bvh_build", &point_bvh_build, "Kept point hierarchy: [nodes, roots, perm, points, slack]");
  m.def("point_bvh_refit", &point_bvh_refit, "Refit a kept point hierarchy to moved points (in place)");
  m.def("point_bvh_query", &point_bvh_query, "Nearest reference point per point (kept hierarchy, exact)");
  m.def("closest_points", &closest_points,
        "Closest point on the selected faces without autograd: [sq_dists, bary, closest] (centred frame)");
  m.def("mpeg_knn", &mpeg_knn,
        "k nearest reference points with mmetric's float32-difference, double-sum distance: [idx (Q, k), sq (Q, k)]");
  m.def("nearest_single", &nearest_single,
        "Batch-of-one nearest reference point, fused: [sq_dists, idx, center], or [] when a value is not finite");
}
