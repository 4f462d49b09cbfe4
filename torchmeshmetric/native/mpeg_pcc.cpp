// mmetric's point-cloud comparison (compare --mode pcc) on CPU threads: the duplicate-position merge as one sort and
// the nearest-neighbour search with mpeg-pcc-dmetric's distance arithmetic and its rule for equidistant neighbours.
//
// Distances are dmetric's: float32 coordinate differences, squares summed in double as (dx*dx + dy*dy) + dz*dz.
// Neighbours are ranked by (squared distance, index), so the answers do not depend on the tree, the thread count or
// the query order. Built with -ffp-contract=off (no fused multiply-add): every operation rounds as written.
#include <torch/extension.h>

#include <ATen/Parallel.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

namespace {

constexpr int LEAF = 8;          // points per kd-tree leaf
constexpr int MAX_K = 30;        // dmetric's num_results_max
constexpr int FIRST_K = 10;      // dmetric's first search of a query with equidistant neighbours
constexpr int STEP_K = 5;        // dmetric's num_results_incr
constexpr double SIMILAR = 1e-20;  // dmetric's similarPointThreshold as mmetric passes it
constexpr double WIDEN = 1.0 + 1e-6;  // see box_gap_sq
constexpr int64_t GRAIN = 512;   // queries per parallel task

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

KdTree build_tree(const float* p, int64_t n) {
  KdTree t;
  std::vector<Slot> sl(static_cast<size_t>(n));
  Box box;
  for (int a = 0; a < 3; ++a) {
    box.lo[a] = std::numeric_limits<float>::infinity();
    box.hi[a] = -std::numeric_limits<float>::infinity();
  }
  for (int64_t i = 0; i < n; ++i) {
    sl[i] = Slot{{p[3 * i], p[3 * i + 1], p[3 * i + 2]}, i};
    for (int a = 0; a < 3; ++a) {
      box.lo[a] = std::min(box.lo[a], p[3 * i + a]);
      box.hi[a] = std::max(box.hi[a], p[3 * i + a]);
    }
  }
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

// The k best (squared distance, index) pairs offered, in rank order.
struct Best {
  int k, n = 0;
  double sq[MAX_K];
  int64_t idx[MAX_K];
  void offer(double s, int64_t i) {
    if (n == k && (s > sq[k - 1] || (s == sq[k - 1] && i >= idx[k - 1]))) return;
    for (int j = 0; j < n; ++j)
      if (idx[j] == i) return;  // the seed met again in the traversal
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

// Depth-first search, nearer child first, of every box within `bound(best)`.
template <typename Bound>
void search(const KdTree& t, const float* q, Best& best, const Bound& bound) {
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

void check_points(const torch::Tensor& p, const char* name) {
  TORCH_CHECK(p.device().is_cpu() && p.is_contiguous() && p.scalar_type() == torch::kFloat32 && p.dim() == 2 &&
                  p.size(1) == 3,
              name, ": contiguous float32 (N, 3) CPU points expected");
  TORCH_CHECK(p.size(0) < std::numeric_limits<int32_t>::max(), name, ": too many points");
}

}  // namespace

// The merge order of dmetric's dropDuplicates: point indices sorted by (x, y, z, index), and the first position of
// every run of equal coordinates (-0.0 equals 0.0). Returns {order (N,), starts (M,)}.
std::vector<torch::Tensor> mpeg_merge_order(torch::Tensor points) {
  check_points(points, "mpeg_merge_order");
  const int64_t n = points.size(0);
  const float* p = points.data_ptr<float>();
  auto order_t = torch::empty({n}, torch::kInt64);
  int64_t* order = order_t.data_ptr<int64_t>();
  for (int64_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order, order + n, [p](int64_t u, int64_t v) {
    const float* a = p + 3 * u;
    const float* b = p + 3 * v;
    if (a[0] != b[0]) return a[0] < b[0];
    if (a[1] != b[1]) return a[1] < b[1];
    if (a[2] != b[2]) return a[2] < b[2];
    return u < v;
  });
  std::vector<int64_t> starts;
  starts.reserve(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) {
    const float* a = p + 3 * order[i];
    const float* b = i > 0 ? p + 3 * order[i - 1] : nullptr;
    if (i == 0 || a[0] != b[0] || a[1] != b[1] || a[2] != b[2]) starts.push_back(i);
  }
  auto starts_t = torch::empty({static_cast<int64_t>(starts.size())}, torch::kInt64);
  std::memcpy(starts_t.data_ptr<int64_t>(), starts.data(), starts.size() * sizeof(int64_t));
  return {order_t, starts_t};
}

// Nearest target point of every query point and dmetric's equidistant neighbours, one pass over the queries:
// the nearest by (squared distance, index), its squared distance, and for the queries whose second nearest is
// within 1e-20 of it ("ties"), the k nearest as dmetric's widening search leaves them (k = 10, then + 5 while all
// k are equally far, at most 30). Returns {nearest (Q,), sq (Q,), tie_rows (S,), cand (S, K), cand_sq (S, K)},
// candidates padded with -1 / inf.
namespace {

// mpeg_nearest_ties over built trees; the queries run in the tree order of their own cloud (near in space).
std::vector<torch::Tensor> nearest_ties(const torch::Tensor& query, const KdTree& qtree, const torch::Tensor& target,
                                        const KdTree& tree) {
  const int64_t Q = query.size(0), T = target.size(0);
  const float* qp = query.data_ptr<float>();
  const float* tp = target.data_ptr<float>();
  auto nearest_t = torch::empty({Q}, torch::kInt64);
  auto sq_t = torch::empty({Q}, torch::kFloat64);
  auto tie_t = torch::zeros({Q}, torch::kBool);
  int64_t* nearest = nearest_t.data_ptr<int64_t>();
  double* sq = sq_t.data_ptr<double>();
  bool* tie = tie_t.data_ptr<bool>();
  // The nearest and the second by rank, searched only as far as a tie could reach: all points within 1e-20 of the
  // nearest are visited, so the second is exact whenever it is a tie, and a farther second is no tie either way.
  const auto tie_bound = [](const Best& b) {
    return b.n == 0 ? std::numeric_limits<double>::infinity() : (b.sq[0] + SIMILAR) * WIDEN;
  };
  at::parallel_for(0, Q, GRAIN, [&](int64_t s0, int64_t e) {
    int64_t prev = -1;
    for (int64_t s = s0; s < e; ++s) {
      const int64_t i = qtree.perm[s];
      const float* q = qp + 3 * i;
      Best best{2};
      if (prev >= 0) {
        const float* r = tp + 3 * prev;
        best.offer(mpeg_sq(q[0], q[1], q[2], r[0], r[1], r[2]), prev);
      }
      search(tree, q, best, tie_bound);
      nearest[i] = best.idx[0];
      sq[i] = best.sq[0];
      tie[i] = best.n == 2 && best.sq[1] - best.sq[0] < SIMILAR;
      prev = best.idx[0];
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
  const auto k_bound = [](const Best& b) {
    return b.n < b.k ? std::numeric_limits<double>::infinity() : b.sq[b.k - 1] * WIDEN;
  };
  int used = kfirst;
  at::parallel_for(0, S, 16, [&](int64_t s0, int64_t e) {
    for (int64_t s = s0; s < e; ++s) {
      Best best{kmax};
      search(tree, qp + 3 * rows[s], best, k_bound);
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
  const KdTree tree = build_tree(target.data_ptr<float>(), target.size(0));
  const KdTree qtree = build_tree(query.data_ptr<float>(), query.size(0));
  return nearest_ties(query, qtree, target, tree);
}

// Both directions of the comparison (a -> b, then b -> a: ten tensors), each cloud's tree built once.
std::vector<torch::Tensor> mpeg_nearest_ties_both(torch::Tensor a, torch::Tensor b) {
  check_points(a, "mpeg_nearest_ties_both: a");
  check_points(b, "mpeg_nearest_ties_both: b");
  TORCH_CHECK(a.size(0) > 0 && b.size(0) > 0, "mpeg_nearest_ties_both: empty cloud");
  const KdTree ta = build_tree(a.data_ptr<float>(), a.size(0));
  const KdTree tb = build_tree(b.data_ptr<float>(), b.size(0));
  std::vector<torch::Tensor> out = nearest_ties(a, ta, b, tb);
  std::vector<torch::Tensor> back = nearest_ties(b, tb, a, ta);
  out.insert(out.end(), back.begin(), back.end());
  return out;
}

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("mpeg_merge_order", &mpeg_merge_order, "dmetric's duplicate merge order (points sorted, run starts)");
  m.def("mpeg_nearest_ties", &mpeg_nearest_ties, "nearest neighbours with dmetric's equidistant-neighbour rule");
  m.def("mpeg_nearest_ties_both", &mpeg_nearest_ties_both, "mpeg_nearest_ties in both directions");
}
