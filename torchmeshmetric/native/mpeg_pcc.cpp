// mmetric's point-cloud comparison (compare --mode pcc) on CPU threads: the duplicate-position merge as one sort and
// the nearest-neighbour search with mpeg-pcc-dmetric's distance arithmetic and its rule for equidistant neighbours.
//
// Distances are dmetric's: float32 coordinate differences, squares summed in double as (dx*dx + dy*dy) + dz*dz.
// Neighbours are ranked by (squared distance, index), so the answers do not depend on the search structure (a grid of
// columns for near queries, a kd-tree for far ones), the thread count or the query order. Built with
// -ffp-contract=off (no fused multiply-add): every operation rounds as written.
#include <torch/extension.h>

#include <ATen/Parallel.h>

#include "parallel.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <mutex>
#include <vector>

namespace {

constexpr int LEAF = 8;          // points per kd-tree leaf
constexpr int MAX_K = 30;        // dmetric's num_results_max
constexpr int FIRST_K = 10;      // dmetric's first search of a query with equidistant neighbours
constexpr int STEP_K = 5;        // dmetric's num_results_incr
constexpr double SIMILAR = 1e-20;  // dmetric's similarPointThreshold as mmetric passes it
// mpeg_sq rounds each float32 difference (relative 2^-24), so it can lie below the exact squared distance by a
// relative 2^-22 at most: a point with mpeg_sq <= b is within sqrt(b * WIDEN) of the query.
constexpr double WIDEN = 1.0 + 1e-6;
constexpr int64_t GRAIN = 512;   // queries per parallel task
constexpr double POINTS_PER_COLUMN = 32.0;  // see build_grid

inline double mpeg_sq(float qx, float qy, float qz, float rx, float ry, float rz) {
  const double dx = static_cast<double>(qx - rx);
  const double dy = static_cast<double>(qy - ry);
  const double dz = static_cast<double>(qz - rz);
  double s = dx * dx + dy * dy;
  s += dz * dz;
  return s;
}

// An inner node holds both children's boxes, so that a pruned child is never read. A child reference >= 0 is an
// inner node; a leaf is ~start (< 0) with its point count.
struct KdNode {
  float lo[2][3], hi[2][3];
  int32_t child[2], count[2];
};

struct Box {
  float lo[3], hi[3];
};

// A kd-tree of median splits on the longest side; the points copied in tree order, one array per coordinate.
struct KdTree {
  std::vector<KdNode> nodes;
  int32_t root = 0, root_count = 0;
  Box root_box{};
  std::vector<int64_t> perm;  // tree slot -> original index
  std::vector<float> xs, ys, zs;
};

struct Slot {
  float c[3];
  int64_t idx;
};

int64_t inner_count(int64_t n) { return n <= LEAF ? 0 : 1 + inner_count(n / 2) + inner_count(n - n / 2); }

// Node over slots [begin, end): the axis is chosen on `approx` (the parent's box cut at the split), the box kept is
// the tight one, from the children up. Inner nodes are numbered in depth-first order from `id`.
int32_t build_node(KdTree& t, Slot* sl, int64_t begin, int64_t end, const Box& approx, int64_t id, Box& tight,
                   bool parallel) {
  if (end - begin <= LEAF) {
    for (int a = 0; a < 3; ++a) {
      tight.lo[a] = std::numeric_limits<float>::infinity();
      tight.hi[a] = -std::numeric_limits<float>::infinity();
    }
    for (int64_t i = begin; i < end; ++i)
      for (int a = 0; a < 3; ++a) {
        tight.lo[a] = std::min(tight.lo[a], sl[i].c[a]);
        tight.hi[a] = std::max(tight.hi[a], sl[i].c[a]);
      }
    return static_cast<int32_t>(~begin);
  }
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (approx.hi[a] - approx.lo[a] > approx.hi[axis] - approx.lo[axis]) axis = a;
  const int64_t mid = begin + (end - begin) / 2;
  std::nth_element(sl + begin, sl + mid, sl + end,
                   [axis](const Slot& u, const Slot& v) { return u.c[axis] < v.c[axis]; });
  Box sub[2] = {approx, approx}, got[2];
  sub[0].hi[axis] = sl[mid].c[axis];
  sub[1].lo[axis] = sl[mid].c[axis];
  const int64_t first[2] = {id + 1, id + 1 + inner_count(mid - begin)};
  const int64_t lo_[2] = {begin, mid}, hi_[2] = {mid, end};
  int32_t ref[2];
  const auto side = [&](int c) { ref[c] = build_node(t, sl, lo_[c], hi_[c], sub[c], first[c], got[c], false); };
  if (parallel) {
    at::parallel_for(0, 2, 1, [&](int64_t b, int64_t e) {
      for (int64_t c = b; c < e; ++c) side(static_cast<int>(c));
    });
  } else {
    side(0);
    side(1);
  }
  KdNode& nd = t.nodes[id];
  for (int c = 0; c < 2; ++c) {
    nd.child[c] = ref[c];
    nd.count[c] = static_cast<int32_t>(hi_[c] - lo_[c]);
    for (int a = 0; a < 3; ++a) {
      nd.lo[c][a] = got[c].lo[a];
      nd.hi[c][a] = got[c].hi[a];
    }
  }
  for (int a = 0; a < 3; ++a) {
    tight.lo[a] = std::min(got[0].lo[a], got[1].lo[a]);
    tight.hi[a] = std::max(got[0].hi[a], got[1].hi[a]);
  }
  return static_cast<int32_t>(id);
}

// The bounding box of n points (x, y, z rows).
Box bounds(const float* p, int64_t n) {
  Box box;
  for (int a = 0; a < 3; ++a) {
    box.lo[a] = std::numeric_limits<float>::infinity();
    box.hi[a] = -std::numeric_limits<float>::infinity();
  }
  for (int64_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      box.lo[a] = std::min(box.lo[a], p[3 * i + a]);
      box.hi[a] = std::max(box.hi[a], p[3 * i + a]);
    }
  return box;
}

KdTree build_tree(const float* p, int64_t n) {
  KdTree t;
  std::vector<Slot> sl(static_cast<size_t>(n));
  const Box box = bounds(p, n);
  for (int64_t i = 0; i < n; ++i) sl[i] = Slot{{p[3 * i], p[3 * i + 1], p[3 * i + 2]}, i};
  t.nodes.resize(static_cast<size_t>(inner_count(n)));
  t.root = build_node(t, sl.data(), 0, n, box, 0, t.root_box, true);
  t.root_count = static_cast<int32_t>(n);
  // padded by a leaf so that every leaf's distances are computed in one straight loop
  t.perm.resize(n);
  t.xs.assign(n + LEAF, 0.0f);
  t.ys.assign(n + LEAF, 0.0f);
  t.zs.assign(n + LEAF, 0.0f);
  for (int64_t i = 0; i < n; ++i) {
    t.perm[i] = sl[i].idx;
    t.xs[i] = sl[i].c[0];
    t.ys[i] = sl[i].c[1];
    t.zs[i] = sl[i].c[2];
  }
  return t;
}

// Lower bound of mpeg_sq over a box, per axis the gap in double. The float32 difference of a point in the box can
// round below the exact gap by a relative 2^-24, so callers compare it with their bound widened by WIDEN.
inline double box_gap_sq(const float* lo, const float* hi, const float* q) {
  double s = 0;
  for (int a = 0; a < 3; ++a) {
    const double d = std::max({static_cast<double>(lo[a]) - q[a], static_cast<double>(q[a]) - hi[a], 0.0});
    s += d * d;
  }
  return s;
}

// A grid of columns: the plane of the two shorter sides of the box cut into square cells of side h, each cell's
// points sorted along the longest side (ties by index) and stored in that order, one array per coordinate. A
// search visits the columns within a radius of the query and, in each, the points within the radius along the
// column by binary search. Sampled surfaces have a nearly even density, so a radius of a few point spacings
// visits a few columns and a few dozen points.
struct ColumnGrid {
  int a0 = 0, a1 = 1, ac = 2;  // the column plane's axes and the column axis
  double o0 = 0, o1 = 0, inv_h = 1;
  int64_t g0 = 1, g1 = 1;
  std::vector<int64_t> start;  // g0 * g1 + 1 column offsets
  std::vector<float> xyz[3];   // per coordinate, in column order
  std::vector<int64_t> idx;    // column order -> original index
  // monotone in u, so a point in [lo, hi] lies in a column between cell(lo) and cell(hi)
  int64_t cell(double u, double o, int64_t g) const {
    const double c = std::floor((u - o) * inv_h);
    return c < 0 ? 0 : (c >= static_cast<double>(g) ? g - 1 : static_cast<int64_t>(c));
  }
  int64_t column_of(const float* p) const { return cell(p[a0], o0, g0) * g1 + cell(p[a1], o1, g1); }
};

// The points in the column order of grid g: by column, then along the column axis (ties by index); the column
// offsets in `start` when asked.
std::vector<int64_t> column_order(const ColumnGrid& g, const float* p, int64_t n, std::vector<int64_t>* start) {
  const int64_t cols = g.g0 * g.g1;
  std::vector<int64_t> col(static_cast<size_t>(n));
  at::parallel_for(0, n, 1 << 14, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) col[i] = g.column_of(p + 3 * i);
  });
  std::vector<int64_t> first(static_cast<size_t>(cols + 1), 0);
  for (int64_t i = 0; i < n; ++i) ++first[col[i] + 1];
  for (int64_t c = 0; c < cols; ++c) first[c + 1] += first[c];
  std::vector<int64_t> order(static_cast<size_t>(n));
  {
    std::vector<int64_t> fill(first.begin(), first.end() - 1);
    for (int64_t i = 0; i < n; ++i) order[fill[col[i]]++] = i;  // ascending index within a column
  }
  const int ac = g.ac;
  tmm::chunked_for(cols, 256, [&](int64_t b, int64_t e) {
    for (int64_t c = b; c < e; ++c)
      std::stable_sort(order.begin() + first[c], order.begin() + first[c + 1],
                       [p, ac](int64_t u, int64_t v) { return p[3 * u + ac] < p[3 * v + ac]; });
  });
  if (start != nullptr) *start = std::move(first);
  return order;
}

ColumnGrid build_grid(const float* p, int64_t n) {
  ColumnGrid g;
  const Box box = bounds(p, n);
  const float *lo = box.lo, *hi = box.hi;
  double ext[3];
  for (int a = 0; a < 3; ++a) ext[a] = static_cast<double>(hi[a]) - static_cast<double>(lo[a]);
  g.ac = 0;
  for (int a = 1; a < 3; ++a)
    if (ext[a] > ext[g.ac]) g.ac = a;
  g.a0 = g.ac == 0 ? 1 : 0;
  g.a1 = g.ac == 2 ? 1 : 2;
  // about POINTS_PER_COLUMN points per column if they filled the plane's rectangle (8 to 128 search alike on
  // grid-sampled frames; 2 is four times slower), at most 2048 x 2048 columns
  const double area = std::max(ext[g.a0], 1e-30) * std::max(ext[g.a1], 1e-30);
  double h = std::sqrt(area * POINTS_PER_COLUMN / static_cast<double>(std::max<int64_t>(n, 1)));
  const double max_cells = 2048.0;
  h = std::max({h, ext[g.a0] / max_cells, ext[g.a1] / max_cells, 1e-30});
  g.inv_h = 1.0 / h;
  g.o0 = lo[g.a0];
  g.o1 = lo[g.a1];
  g.g0 = std::max<int64_t>(1, std::min<int64_t>(static_cast<int64_t>(ext[g.a0] * g.inv_h) + 1, 2048));
  g.g1 = std::max<int64_t>(1, std::min<int64_t>(static_cast<int64_t>(ext[g.a1] * g.inv_h) + 1, 2048));
  g.idx = column_order(g, p, n, &g.start);
  for (int a = 0; a < 3; ++a) g.xyz[a].resize(static_cast<size_t>(n));
  at::parallel_for(0, n, 1 << 14, [&](int64_t b, int64_t e) {
    for (int64_t s = b; s < e; ++s)
      for (int a = 0; a < 3; ++a) g.xyz[a][s] = p[3 * g.idx[s] + a];
  });
  return g;
}

// The k best (squared distance, index) pairs offered, in rank order.
struct Best {
  int k, n = 0;
  double sq[MAX_K];
  int64_t idx[MAX_K];
  void offer(double s, int64_t i) {
    if (n == k && (s > sq[k - 1] || (s == sq[k - 1] && i >= idx[k - 1]))) return;
    for (int j = 0; j < n; ++j)
      if (idx[j] == i) return;  // the seed met again
    int j = n < k ? n++ : k - 1;
    while (j > 0 && (sq[j - 1] > s || (sq[j - 1] == s && idx[j - 1] > i))) {
      sq[j] = sq[j - 1];
      idx[j] = idx[j - 1];
      --j;
    }
    sq[j] = s;
    idx[j] = i;
  }
  double keep() const { return n < k ? std::numeric_limits<double>::infinity() : sq[k - 1]; }
};

// Depth-first search of the kd-tree, nearer child first, of every box within `bound(best)` (a bound widened by
// WIDEN: box gaps are exact, the float32 differences of the points inside may be smaller).
template <typename Bound>
void kd_search(const KdTree& t, const float* q, Best& best, const Bound& bound) {
  const KdNode* nd = t.nodes.data();
  int32_t stack[64], stack_n[64];
  double stack_d[64];
  int top = 0;
  int32_t ref = t.root, cnt = t.root_count;
  double dn = box_gap_sq(t.root_box.lo, t.root_box.hi, q);
  double b = bound(best);
  for (;;) {
    if (dn <= b) {
      if (ref < 0) {
        const int32_t start = ~ref;
        double sq[LEAF];
        for (int l = 0; l < LEAF; ++l) {
          const int32_t j = start + l;
          sq[l] = mpeg_sq(q[0], q[1], q[2], t.xs[j], t.ys[j], t.zs[j]);
        }
        const double keep = best.n < best.k ? std::numeric_limits<double>::infinity() : best.sq[best.k - 1];
        for (int l = 0; l < cnt; ++l)
          if (sq[l] <= keep) best.offer(sq[l], t.perm[start + l]);
        b = bound(best);
      } else {
        const KdNode& node = nd[ref];
        const double d0 = box_gap_sq(node.lo[0], node.hi[0], q), d1 = box_gap_sq(node.lo[1], node.hi[1], q);
        const int near = d0 <= d1 ? 0 : 1;
        const double dfar = near == 0 ? d1 : d0;
        if (dfar <= b) {
          stack[top] = node.child[1 - near];
          stack_n[top] = node.count[1 - near];
          stack_d[top] = dfar;
          ++top;
        }
        ref = node.child[near];
        cnt = node.count[near];
        dn = near == 0 ? d0 : d1;
        continue;
      }
    }
    if (top == 0) break;
    --top;
    ref = stack[top];
    cnt = stack_n[top];
    dn = stack_d[top];
  }
}


// u - r and u + r rounded outwards (a double subtraction is off by half an ulp of its result at most)
inline double down(double u, double r) {
  const double v = u - r;
  return v - (std::abs(v) * 1e-15 + 1e-300);
}
inline double up(double u, double r) {
  const double v = u + r;
  return v + (std::abs(v) * 1e-15 + 1e-300);
}

// Offers every point of the columns within r of q along the plane and within r along the column: a superset of the
// points whose exact distance to q is at most r.
void visit(const ColumnGrid& g, const float* q, double r, Best& best) {
  const double qa = q[g.a0], qb = q[g.a1], qc = q[g.ac];
  const int64_t c0 = g.cell(down(qa, r), g.o0, g.g0), c1 = g.cell(up(qa, r), g.o0, g.g0);
  const int64_t d0 = g.cell(down(qb, r), g.o1, g.g1), d1 = g.cell(up(qb, r), g.o1, g.g1);
  const double zlo = down(qc, r), zhi = up(qc, r);
  const float* zs = g.xyz[g.ac].data();
  const float *xs = g.xyz[0].data(), *ys = g.xyz[1].data(), *ws = g.xyz[2].data();
  for (int64_t c = c0; c <= c1; ++c)
    for (int64_t d = d0; d <= d1; ++d) {
      const int64_t col = c * g.g1 + d;
      const float* first = zs + g.start[col];
      const float* last = zs + g.start[col + 1];
      if (first == last) continue;
      // std::lower_bound's answer (the first z >= zlo) without its unpredictable branches: the range holding the
      // answer halved by a conditional move
      const float* it = first;
      for (int64_t len = last - first; len > 1;) {
        const int64_t half = len / 2;
        it = it[half - 1] < zlo ? it + half : it;
        len -= half;
      }
      if (it != last && *it < zlo) ++it;
      for (; it != last && *it <= zhi; ++it) {
        const int64_t s = it - zs;
        const double sq = mpeg_sq(q[0], q[1], q[2], xs[s], ys[s], ws[s]);
        if (sq <= best.keep()) best.offer(sq, g.idx[s]);
      }
    }
}

// The points ranked by (mpeg_sq, index) up to what `bound(best)` asks: visits within a radius r0, and while a point
// within the bound could lie beyond the radius visited, again within a larger radius, up to r_max. Returns whether
// the answer is complete (it then depends on the points only, not on the grid, the seed or r0); past r_max the
// column grid would visit many columns and points per query, and the caller searches the kd-tree instead.
template <typename Bound>
bool search(const ColumnGrid& g, const float* q, int64_t seed, const float* tp, double r0, double r_max, Best& best,
            const Bound& bound) {
  for (double r = r0;;) {
    best.n = 0;
    if (seed >= 0) {
      const float* s = tp + 3 * seed;
      best.offer(mpeg_sq(q[0], q[1], q[2], s[0], s[1], s[2]), seed);
    }
    visit(g, q, r, best);
    const double b = bound(best) * WIDEN;
    if (b <= r * r) return true;
    if (r >= r_max) return false;
    r = std::min(r_max, std::isfinite(b) ? std::max(2 * r, std::sqrt(b) * (1 + 1e-6)) : 2 * r);
  }
}

// The kd-tree of a cloud, built on first use (only clouds with queries far from them need one).
class LazyTree {
 public:
  LazyTree(const float* p, int64_t n) : p_(p), n_(n) {}
  const KdTree& get() {
    std::call_once(once_, [this] { tree_ = build_tree(p_, n_); });
    return tree_;
  }

 private:
  const float* p_;
  int64_t n_;
  std::once_flag once_;
  KdTree tree_;
};

void check_points(const torch::Tensor& p, const char* name) {
  TORCH_CHECK(p.device().is_cpu() && p.is_contiguous() && p.scalar_type() == torch::kFloat32 && p.dim() == 2 &&
                  p.size(1) == 3,
              name, ": contiguous float32 (N, 3) CPU points expected");
  TORCH_CHECK(p.size(0) < std::numeric_limits<int32_t>::max(), name, ": too many points");
}

}  // namespace

namespace {

// A float's bits mapped so that unsigned order is numeric order (-0.0 first made 0.0: they are one coordinate).
inline uint64_t ordered_bits(float f) {
  f = f + 0.0F;
  uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return (b & 0x80000000U) ? ~b : (b | 0x80000000U);
}

struct SortKey {
  uint64_t hi, lo;  // (x, y), (z, index)
  bool operator<(const SortKey& o) const { return hi != o.hi ? hi < o.hi : lo < o.lo; }
  bool same_point(const SortKey& o) const { return hi == o.hi && (lo >> 32) == (o.lo >> 32); }
};

// Points sorted by (x, y, z, index): keys sorted directly (no comparator reading the points).
std::vector<SortKey> sorted_keys(const float* p, int64_t n) {
  std::vector<SortKey> keys(static_cast<size_t>(n));
  at::parallel_for(0, n, 1 << 14, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i)
      keys[i] = {(ordered_bits(p[3 * i]) << 32) | ordered_bits(p[3 * i + 1]),
                 (ordered_bits(p[3 * i + 2]) << 32) | static_cast<uint64_t>(i)};
  });
  tmm::parallel_sort(keys);
  return keys;
}

}  // namespace

// dmetric's dropDuplicates = 2 (average): the points sorted by (x, y, z), ties by index; each run of equal coordinates
// (-0.0 equals 0.0) becomes one point whose normal is the float32 mean of the run's normals (summed in run order, not
// renormalised) and whose colour is the integer mean (truncated) of the colours rounded to 8 bits (roundf, clamped;
// NaN as 0, as mmetric's int conversion gives on x86). normals / colors may be empty (0 elements): their result is
// empty too. Returns {points (M, 3), normals (M, 3), colors (M, 3) float32}.
std::vector<torch::Tensor> mpeg_merge(torch::Tensor points, torch::Tensor normals, torch::Tensor colors) {
  check_points(points, "mpeg_merge");
  const int64_t n = points.size(0);
  const bool with_n = normals.numel() > 0, with_c = colors.numel() > 0;
  if (with_n) check_points(normals, "mpeg_merge: normals");
  if (with_c) check_points(colors, "mpeg_merge: colors");
  TORCH_CHECK(!with_n || normals.size(0) == n, "mpeg_merge: normals and points differ in count");
  TORCH_CHECK(!with_c || colors.size(0) == n, "mpeg_merge: colors and points differ in count");
  const float* p = points.data_ptr<float>();
  std::vector<SortKey> keys = sorted_keys(p, n);
  std::vector<int64_t> starts;
  starts.reserve(static_cast<size_t>(n) + 1);
  for (int64_t i = 0; i < n; ++i)
    if (i == 0 || !keys[i].same_point(keys[i - 1])) starts.push_back(i);
  const int64_t m = static_cast<int64_t>(starts.size());
  starts.push_back(n);
  auto out_p = torch::empty({m, 3}, torch::kFloat32);
  auto out_n = with_n ? torch::empty({m, 3}, torch::kFloat32) : torch::empty({0, 3}, torch::kFloat32);
  auto out_c = with_c ? torch::empty({m, 3}, torch::kFloat32) : torch::empty({0, 3}, torch::kFloat32);
  float* op = out_p.data_ptr<float>();
  float* on = with_n ? out_n.data_ptr<float>() : nullptr;
  float* oc = with_c ? out_c.data_ptr<float>() : nullptr;
  const float* nrm = with_n ? normals.data_ptr<float>() : nullptr;
  const float* col = with_c ? colors.data_ptr<float>() : nullptr;
  at::parallel_for(0, m, 1 << 12, [&](int64_t b, int64_t e) {
    for (int64_t r = b; r < e; ++r) {
      const int64_t s = starts[r], t = starts[r + 1];
      const int64_t first = static_cast<int64_t>(keys[s].lo & 0xffffffffU);
      for (int a = 0; a < 3; ++a) op[3 * r + a] = p[3 * first + a];
      if (with_n) {
        float sum[3] = {0.0F, 0.0F, 0.0F};
        for (int64_t i = s; i < t; ++i) {
          const int64_t j = static_cast<int64_t>(keys[i].lo & 0xffffffffU);
          for (int a = 0; a < 3; ++a) sum[a] += nrm[3 * j + a];
        }
        for (int a = 0; a < 3; ++a) on[3 * r + a] = sum[a] / static_cast<float>(t - s);
      }
      if (with_c) {
        int64_t sum[3] = {0, 0, 0};
        for (int64_t i = s; i < t; ++i) {
          const int64_t j = static_cast<int64_t>(keys[i].lo & 0xffffffffU);
          for (int a = 0; a < 3; ++a) {
            const double v = std::floor(static_cast<double>(col[3 * j + a]) + 0.5);
            sum[a] += std::isnan(v) ? 0 : static_cast<int64_t>(std::min(255.0, std::max(0.0, v)));
          }
        }
        for (int a = 0; a < 3; ++a) oc[3 * r + a] = static_cast<float>(sum[a] / (t - s));
      }
    }
  });
  return {out_p, out_n, out_c};
}

// Nearest target point of every query point and dmetric's equidistant neighbours, one pass over the queries:
// the nearest by (squared distance, index), its squared distance, and for the queries whose second nearest is
// within 1e-20 of it ("ties"), the k nearest as dmetric's widening search leaves them (k = 10, then + 5 while all
// k are equally far, at most 30). Returns {nearest (Q,), sq (Q,), tie_rows (S,), cand (S, K), cand_sq (S, K)},
// candidates padded with -1 / inf.
namespace {

// mpeg_nearest_ties over the target's grid; the queries run in that grid's column order (consecutive queries visit
// the same columns), each seeded with the previous one's nearest point. Queries whose answer lies farther than two
// column sides (clouds far apart) are answered by the target's kd-tree, with the same ranking, and so is the next
// query after such an answer (until an answer lies within reach again).
std::vector<torch::Tensor> nearest_ties(const torch::Tensor& query, const torch::Tensor& target,
                                        const ColumnGrid& grid, LazyTree& tree) {
  const int64_t Q = query.size(0), T = target.size(0);
  const float* qp = query.data_ptr<float>();
  const float* tp = target.data_ptr<float>();
  auto nearest_t = torch::empty({Q}, torch::kInt64);
  auto sq_t = torch::empty({Q}, torch::kFloat64);
  auto tie_t = torch::zeros({Q}, torch::kBool);
  int64_t* nearest = nearest_t.data_ptr<int64_t>();
  double* sq = sq_t.data_ptr<double>();
  bool* tie = tie_t.data_ptr<bool>();
  const double h = 1.0 / grid.inv_h, r_max = 2 * h;
  const std::vector<int64_t> qorder = column_order(grid, qp, Q, nullptr);
  std::vector<float> qs(static_cast<size_t>(3 * Q));  // the queries in that order, read in sequence
  at::parallel_for(0, Q, 1 << 14, [&](int64_t b, int64_t e) {
    for (int64_t s = b; s < e; ++s)
      for (int a = 0; a < 3; ++a) qs[3 * s + a] = qp[3 * qorder[s] + a];
  });
  // The nearest and the second by rank, searched only as far as a tie could reach: all points within 1e-20 of the
  // nearest are visited, so the second is exact whenever it is a tie, and a farther second is no tie either way.
  const auto tie_bound = [](const Best& b) {
    return b.n == 0 ? std::numeric_limits<double>::infinity() : b.sq[0] + SIMILAR;
  };
  const auto kd_tie_bound = [&](const Best& b) { return tie_bound(b) * WIDEN; };
  tmm::chunked_for(Q, GRAIN, [&](int64_t s0, int64_t e) {
    int64_t prev = -1;
    bool far = false;  // the previous answer lay beyond the grid's reach: go to the kd-tree at once
    double dprev = 0;  // the previous query's nearest distance
    for (int64_t s = s0; s < e; ++s) {
      const int64_t i = qorder[s];
      const float* q = qs.data() + 3 * s;
      Best best{2};
      // the previous query's nearest point bounds the radius when it is near (most queries: the next point of the
      // same column); a column's first query starts from one column side
      double r0 = h;
      if (prev >= 0) {
        const float* t = tp + 3 * prev;
        r0 = std::min(h, std::sqrt((mpeg_sq(q[0], q[1], q[2], t[0], t[1], t[2]) + SIMILAR) * WIDEN) * (1 + 1e-6));
        // and within that, twice the previous query's nearest distance (the points of a sampled surface lie about as
        // far from the other cloud as their neighbours; a query whose answer lies farther widens its radius: search),
        // at least an eighth of a column side. The points visited grow with the square of the radius: this one
        // visits about half as many as the distance to the previous nearest point alone.
        r0 = std::min(r0, std::max(2 * dprev, h / 8));
      }
      if (far || !search(grid, q, prev, tp, r0, r_max, best, tie_bound)) {
        best.n = 0;
        if (prev >= 0) {
          const float* t = tp + 3 * prev;
          best.offer(mpeg_sq(q[0], q[1], q[2], t[0], t[1], t[2]), prev);
        }
        kd_search(tree.get(), q, best, kd_tie_bound);
      }
      nearest[i] = best.idx[0];
      sq[i] = best.sq[0];
      tie[i] = best.n == 2 && best.sq[1] - best.sq[0] < SIMILAR;
      far = best.sq[0] > r_max * r_max;
      prev = best.idx[0];
      dprev = std::sqrt(best.sq[0]);
    }
  });
  auto rows_t = torch::nonzero(tie_t).reshape({-1}).contiguous();
  const int64_t S = rows_t.size(0);
  const int kmax = static_cast<int>(std::min<int64_t>(MAX_K, T));
  const int kfirst = static_cast<int>(std::min<int64_t>(FIRST_K, T));
  auto cand_t = torch::full({S, kmax}, -1, torch::kInt64);
  auto csq_t = torch::full({S, kmax}, std::numeric_limits<double>::infinity(), torch::kFloat64);
  const int64_t* rows = rows_t.data_ptr<int64_t>();
  int64_t* cand = cand_t.data_ptr<int64_t>();
  double* csq = csq_t.data_ptr<double>();
  const auto k_bound = [](const Best& b) { return b.keep(); };
  const auto kd_k_bound = [](const Best& b) { return b.keep() * WIDEN; };
  int used = kfirst;
  tmm::chunked_for(S, 16, [&](int64_t s0, int64_t e) {
    for (int64_t s = s0; s < e; ++s) {
      Best best{kmax};
      const float* q = qp + 3 * rows[s];
      if (!search(grid, q, nearest[rows[s]], tp, h, r_max, best, k_bound)) {
        best.n = 0;
        kd_search(tree.get(), q, best, kd_k_bound);
      }
      // dmetric's widening: the first 10, then 5 more while the k found are all equally far; the ranking by
      // (distance, index) makes the first k of the 30 nearest the k nearest
      int k = kfirst;
      while (k + STEP_K <= kmax && best.sq[0] == best.sq[k - 1]) k += STEP_K;
      for (int a = 0; a < k; ++a) {
        cand[s * kmax + a] = best.idx[a];
        csq[s * kmax + a] = best.sq[a];
      }
    }
  });
  for (int64_t s = 0; s < S; ++s)
    for (int a = used; a < kmax; ++a)
      if (cand[s * kmax + a] >= 0) used = a + 1;
  return {nearest_t, sq_t, rows_t, cand_t.narrow(1, 0, used).contiguous(), csq_t.narrow(1, 0, used).contiguous()};
}

}  // namespace

std::vector<torch::Tensor> mpeg_nearest_ties(torch::Tensor query, torch::Tensor target) {
  check_points(query, "mpeg_nearest_ties: query");
  check_points(target, "mpeg_nearest_ties: target");
  TORCH_CHECK(target.size(0) > 0, "mpeg_nearest_ties: empty target");
  const ColumnGrid grid = build_grid(target.data_ptr<float>(), target.size(0));
  LazyTree tree(target.data_ptr<float>(), target.size(0));
  return nearest_ties(query, target, grid, tree);
}

// Both directions of the comparison (a -> b, then b -> a: ten tensors), each cloud's grid built once.
std::vector<torch::Tensor> mpeg_nearest_ties_both(torch::Tensor a, torch::Tensor b) {
  check_points(a, "mpeg_nearest_ties_both: a");
  check_points(b, "mpeg_nearest_ties_both: b");
  TORCH_CHECK(a.size(0) > 0 && b.size(0) > 0, "mpeg_nearest_ties_both: empty cloud");
  const ColumnGrid ga = build_grid(a.data_ptr<float>(), a.size(0));
  const ColumnGrid gb = build_grid(b.data_ptr<float>(), b.size(0));
  LazyTree ta(a.data_ptr<float>(), a.size(0)), tb(b.data_ptr<float>(), b.size(0));
  std::vector<torch::Tensor> out = nearest_ties(a, b, gb, tb);
  std::vector<torch::Tensor> back = nearest_ties(b, a, ga, ta);
  out.insert(out.end(), back.begin(), back.end());
  return out;
}

// dmetric's squared point-to-plane error of each (query row, target col) pair: the float32 difference projected on
// the target's normal in float32, squared in float32 and returned in double; for a normal with a NaN component,
// dmetric's fallback, the plain float32 sum of the difference's components. Returns (P,) float64.
torch::Tensor mpeg_plane_errors(torch::Tensor query, torch::Tensor target, torch::Tensor normals, torch::Tensor rows,
                                torch::Tensor cols) {
  check_points(query, "mpeg_plane_errors: query");
  check_points(target, "mpeg_plane_errors: target");
  check_points(normals, "mpeg_plane_errors: normals");
  TORCH_CHECK(normals.size(0) == target.size(0), "mpeg_plane_errors: one normal per target point expected");
  TORCH_CHECK(rows.scalar_type() == torch::kInt64 && cols.scalar_type() == torch::kInt64 && rows.is_contiguous() &&
                  cols.is_contiguous() && rows.dim() == 1 && rows.sizes() == cols.sizes(),
              "mpeg_plane_errors: rows and cols: contiguous int64 (P,) expected");
  const int64_t n = rows.size(0);
  const float *qp = query.data_ptr<float>(), *tp = target.data_ptr<float>(), *np_ = normals.data_ptr<float>();
  const int64_t *r = rows.data_ptr<int64_t>(), *c = cols.data_ptr<int64_t>();
  const int64_t Q = query.size(0), T = target.size(0);
  for (int64_t k = 0; k < n; ++k)
    TORCH_CHECK(r[k] >= 0 && r[k] < Q && c[k] >= 0 && c[k] < T, "mpeg_plane_errors: index out of range");
  auto out_t = torch::empty({n}, torch::kFloat64);
  double* out = out_t.data_ptr<double>();
  at::parallel_for(0, n, 1 << 14, [&](int64_t b, int64_t e) {
    for (int64_t k = b; k < e; ++k) {
      const float* q = qp + 3 * r[k];
      const float* t = tp + 3 * c[k];
      const float* nn = np_ + 3 * c[k];
      const float d0 = q[0] - t[0], d1 = q[1] - t[1], d2 = q[2] - t[2];
      if (std::isnan(nn[0]) || std::isnan(nn[1]) || std::isnan(nn[2])) {
        out[k] = static_cast<double>((d0 + d1) + d2);
      } else {
        const float proj = (d0 * nn[0] + d1 * nn[1]) + d2 * nn[2];
        out[k] = static_cast<double>(proj * proj);
      }
    }
  });
  return out_t;
}

// point_order.cpp (compiled into the same extension).
torch::Tensor introsort_permutation(const torch::Tensor& rank);
// model_text.cpp (compiled into the same extension).
pybind11::bytes format_model_rows(const torch::Tensor& floats, const torch::Tensor& ints, const std::string& prefix,
                                  const std::vector<std::string>& seps);

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("format_model_rows", &format_model_rows, "rows of mmetric's model files: %.9g floats, integers, separators");
  m.def("introsort_permutation", &introsort_permutation, "the permutation libstdc++'s std::sort leaves, by rank");
  m.def("mpeg_plane_errors", &mpeg_plane_errors, "dmetric's squared point-to-plane error per (query, target) pair");
  m.def("mpeg_merge", &mpeg_merge, "dmetric's duplicate merge (dropDuplicates = 2): sorted, runs averaged");
  m.def("mpeg_nearest_ties", &mpeg_nearest_ties, "nearest neighbours with dmetric's equidistant-neighbour rule");
  m.def("mpeg_nearest_ties_both", &mpeg_nearest_ties_both, "mpeg_nearest_ties in both directions");
}
