// PCQM (Meynet et al., QoMEX 2020) as mmetric v1.1.7 embeds it (compare --mode pcqm), on CPU threads.
//
// Per point of the registered cloud (mmetric's model A): a quadric fitted to its k nearest reference points gives its
// projection on the reference surface; quadrics fitted to the points within `radius` give the mean curvature on both
// clouds. Then, over a Gaussian-weighted neighbourhood of radius `radius * factor`, the curvature structure term and
// the lightness terms are pooled into per-point features that the Python side combines.
//
// Which neighbours are found, in which order, and how ties are broken follow the k-d tree mmetric uses (nanoflann
// 1.2.3: leaves of at most 10 points, middle splits, double distances (dx*dx + dy*dy) + dz*dz, first-found wins among
// equal distances, radius test `d < r^2`), so that equidistant neighbours -- frequent on sampled clouds -- are the
// same ones. The local frame and the least-squares quadric follow Eigen 3.3.5 (as bundled with mmetric, SSE2) operation
// for operation: its symmetric eigensolver, and its column-pivoting Householder QR with its pivots, its rank rule, its
// basic solution for the many rank-deficient neighbourhoods of fewer than 6 points and its vectorised summation
// orders. Neighbourhoods of 1 or 2 points have a frame fixed by rounding alone, and ill-conditioned fits amplify last
// bits into the printed figures, so nothing less reproduces mm; the per-point fields are bit-identical to PCQM's.
// The points are shared among threads in chunks that an idle thread takes over (tmm::chunked_for): each point's
// figures are independent, and the three sums are added in point order afterwards, so the thread count changes
// nothing. Built with -ffp-contract=off: every operation rounds as written.
#include <torch/extension.h>

#include <ATen/Parallel.h>

#include "parallel.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace {

constexpr int64_t LEAF_MAX = 10;  // nanoflann's KDTreeSingleIndexAdaptorParams(10) in PCQM
constexpr int64_t GRAIN = 256;    // queries per parallel task

struct Node {
  int64_t left = 0, right = 0;  // leaf range in `vind`
  int32_t child1 = -1, child2 = -1, divfeat = 0;
  double divlow = 0.0, divhigh = 0.0;
};

struct Tree {
  const double* p = nullptr;  // (n, 3) row-major
  int64_t n = 0;
  std::vector<int64_t> vind;
  std::vector<Node> nodes;
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  int32_t root = -1;

  double at(int64_t i, int d) const { return p[3 * i + d]; }
  double dist(const double* q, int64_t i) const {
    const double d0 = q[0] - p[3 * i], d1 = q[1] - p[3 * i + 1], d2 = q[2] - p[3 * i + 2];
    return d0 * d0 + d1 * d1 + d2 * d2;
  }

  void min_max(const int64_t* ind, int64_t count, int d, double& mn, double& mx) const {
    mn = mx = at(ind[0], d);
    for (int64_t i = 1; i < count; ++i) {
      const double v = at(ind[i], d);
      if (v < mn) mn = v;
      if (v > mx) mx = v;
    }
  }

  // Partition: [0, lim1) < cut, [lim1, lim2) == cut, [lim2, count) > cut -- the same swaps as nanoflann's.
  void plane_split(int64_t* ind, int64_t count, int d, double cut, int64_t& lim1, int64_t& lim2) const {
    int64_t l = 0, r = count - 1;
    for (;;) {
      while (l <= r && at(ind[l], d) < cut) ++l;
      while (r && l <= r && at(ind[r], d) >= cut) --r;
      if (l > r || !r) break;
      std::swap(ind[l], ind[r]);
      ++l;
      --r;
    }
    lim1 = l;
    r = count - 1;
    for (;;) {
      while (l <= r && at(ind[l], d) <= cut) ++l;
      while (r && l <= r && at(ind[r], d) > cut) --r;
      if (l > r || !r) break;
      std::swap(ind[l], ind[r]);
      ++l;
      --r;
    }
    lim2 = l;
  }

  void middle_split(int64_t* ind, int64_t count, const double* blo, const double* bhi, int64_t& index, int& cutfeat,
                    double& cutval) const {
    const double eps = 0.00001;
    double max_span = bhi[0] - blo[0];
    for (int i = 1; i < 3; ++i) max_span = std::max(max_span, bhi[i] - blo[i]);
    double max_spread = -1;
    cutfeat = 0;
    for (int i = 0; i < 3; ++i) {
      if (bhi[i] - blo[i] > (1 - eps) * max_span) {
        double mn, mx;
        min_max(ind, count, i, mn, mx);
        if (mx - mn > max_spread) {
          cutfeat = i;
          max_spread = mx - mn;
        }
      }
    }
    const double split = (blo[cutfeat] + bhi[cutfeat]) / 2;
    double mn, mx;
    min_max(ind, count, cutfeat, mn, mx);
    cutval = split < mn ? mn : (split > mx ? mx : split);
    int64_t lim1, lim2;
    plane_split(ind, count, cutfeat, cutval, lim1, lim2);
    index = lim1 > count / 2 ? lim1 : (lim2 < count / 2 ? lim2 : count / 2);
  }

  // Builds the subtree of vind[left, right); on return (blo, bhi) is its tight box, as nanoflann's divideTree.
  int32_t divide(int64_t left, int64_t right, double* blo, double* bhi) {
    const int32_t id = static_cast<int32_t>(nodes.size());
    nodes.emplace_back();
    if (right - left <= LEAF_MAX) {
      nodes[id].left = left;
      nodes[id].right = right;
      for (int i = 0; i < 3; ++i) blo[i] = bhi[i] = at(vind[left], i);
      for (int64_t k = left + 1; k < right; ++k)
        for (int i = 0; i < 3; ++i) {
          const double v = at(vind[k], i);
          if (blo[i] > v) blo[i] = v;
          if (bhi[i] < v) bhi[i] = v;
        }
      return id;
    }
    int64_t idx;
    int cutfeat;
    double cutval;
    middle_split(vind.data() + left, right - left, blo, bhi, idx, cutfeat, cutval);
    double llo[3], lhi[3], rlo[3], rhi[3];
    for (int i = 0; i < 3; ++i) llo[i] = rlo[i] = blo[i], lhi[i] = rhi[i] = bhi[i];
    lhi[cutfeat] = cutval;
    const int32_t c1 = divide(left, left + idx, llo, lhi);
    rlo[cutfeat] = cutval;
    const int32_t c2 = divide(left + idx, right, rlo, rhi);
    Node& node = nodes[id];
    node.child1 = c1;
    node.child2 = c2;
    node.divfeat = cutfeat;
    node.divlow = lhi[cutfeat];
    node.divhigh = rlo[cutfeat];
    for (int i = 0; i < 3; ++i) blo[i] = std::min(llo[i], rlo[i]), bhi[i] = std::max(lhi[i], rhi[i]);
    return id;
  }

  void build(const double* pts, int64_t count) {
    p = pts;
    n = count;
    vind.resize(n);
    for (int64_t i = 0; i < n; ++i) vind[i] = i;
    for (int i = 0; i < 3; ++i) lo[i] = hi[i] = at(0, i);
    for (int64_t k = 1; k < n; ++k)
      for (int i = 0; i < 3; ++i) {
        if (at(k, i) < lo[i]) lo[i] = at(k, i);
        if (at(k, i) > hi[i]) hi[i] = at(k, i);
      }
    double blo[3] = {lo[0], lo[1], lo[2]}, bhi[3] = {hi[0], hi[1], hi[2]};
    nodes.reserve(static_cast<size_t>(2 * (n / 4 + 1)));
    root = divide(0, n, blo, bhi);
  }

  // nanoflann's searchLevel: the worst distance is read once per leaf, the nearer child is searched first.
  template <typename R>
  void search_level(R& res, const double* q, int32_t id, double mindistsq, double* dists) const {
    const Node& node = nodes[id];
    if (node.child1 < 0) {
      const double worst = res.worst();
      for (int64_t i = node.left; i < node.right; ++i) {
        const double d = dist(q, vind[i]);
        if (d < worst) res.add(d, vind[i]);
      }
      return;
    }
    const int idx = node.divfeat;
    const double val = q[idx];
    const double diff1 = val - node.divlow, diff2 = val - node.divhigh;
    int32_t best, other;
    double cut;
    if (diff1 + diff2 < 0) {
      best = node.child1, other = node.child2, cut = (val - node.divhigh) * (val - node.divhigh);
    } else {
      best = node.child2, other = node.child1, cut = (val - node.divlow) * (val - node.divlow);
    }
    search_level(res, q, best, mindistsq, dists);
    const double dst = dists[idx];
    mindistsq = mindistsq + cut - dst;
    dists[idx] = cut;
    if (mindistsq <= res.worst()) search_level(res, q, other, mindistsq, dists);
    dists[idx] = dst;
  }

  template <typename R>
  void find(R& res, const double* q) const {
    double dists[3] = {0, 0, 0};
    double distsq = 0;
    for (int i = 0; i < 3; ++i) {
      if (q[i] < lo[i]) dists[i] = (q[i] - lo[i]) * (q[i] - lo[i]), distsq += dists[i];
      if (q[i] > hi[i]) dists[i] = (q[i] - hi[i]) * (q[i] - hi[i]), distsq += dists[i];
    }
    search_level(res, q, root, distsq, dists);
  }
};

// nanoflann's KNNResultSet: sorted insertion, an equal distance goes after the ones already held.
struct Knn {
  int64_t cap, count = 0;
  int64_t* idx;
  double* d;
  Knn(int64_t k, int64_t* i, double* dd) : cap(k), idx(i), d(dd) { d[cap - 1] = DBL_MAX; }
  double worst() const { return d[cap - 1]; }
  void add(double dist, int64_t index) {
    int64_t i;
    for (i = count; i > 0; --i) {
      if (d[i - 1] > dist) {
        if (i < cap) d[i] = d[i - 1], idx[i] = idx[i - 1];
      } else {
        break;
      }
    }
    if (i < cap) d[i] = dist, idx[i] = index;
    if (count < cap) ++count;
  }
};

struct Radius {
  double r;
  std::vector<std::pair<int64_t, double>>* out;
  double worst() const { return r; }
  void add(double dist, int64_t index) {
    if (dist < r) out->emplace_back(index, dist);
  }
};

void radius_search(const Tree& t, const double* q, double r2, bool sorted,
                   std::vector<std::pair<int64_t, double>>& out) {
  out.clear();
  Radius res{r2, &out};
  t.find(res, q);
  if (sorted)  // nanoflann sorts with std::sort on the distance alone (ties keep std::sort's order)
    std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
}

// Eigen 3.3's givens rotation (JacobiRotation::makeGivens, real case).
void make_givens(double p, double q, double& c, double& s) {
  if (q == 0.0) {
    c = p < 0.0 ? -1.0 : 1.0, s = 0.0;
  } else if (p == 0.0) {
    c = 0.0, s = q < 0.0 ? 1.0 : -1.0;
  } else if (std::fabs(p) > std::fabs(q)) {
    const double t = q / p;
    double u = std::sqrt(1.0 + t * t);
    if (p < 0.0) u = -u;
    c = 1.0 / u, s = -t * c;
  } else {
    const double t = p / q;
    double u = std::sqrt(1.0 + t * t);
    if (q < 0.0) u = -u;
    s = -1.0 / u, c = -t * s;
  }
}

double eigen_hypot(double x, double y) {
  x = std::fabs(x), y = std::fabs(y);
  const double p = std::max(x, y);
  if (p == 0.0) return 0.0;
  const double qp = std::min(y, x) / p;
  return p * std::sqrt(1.0 + qp * qp);
}

// The first half of Eigen 3.3's SelfAdjointEigenSolver<MatrixXd>, operation for operation: the lower triangle scaled
// by its largest magnitude, Householder tridiagonalisation (Eigen's scalar symv and rank-2 update orders), Q formed in
// place. The frame of a neighbourhood of one or two points (a zero or rank-one covariance) is fixed by these very
// roundings, and with fewer than 6 points it changes the least-squares basic solution, so an equal-up-to-rounding
// solver is not enough.
void tridiagonalise3(const double a_in[3][3], double diag[3], double sub[2], double q[3][3]) {
  double a[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};  // lower triangle only, as Eigen copies it
  double scale = 0.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j <= i; ++j) a[i][j] = a_in[i][j], scale = std::max(scale, std::fabs(a_in[i][j]));
  if (scale == 0.0) scale = 1.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j <= i; ++j) a[i][j] /= scale;
  // step 0: Householder of (a10, a20)
  double h0, beta0, ess;
  {
    const double c0 = a[1][0], tail = a[2][0] * a[2][0];
    if (tail <= DBL_MIN) {
      h0 = 0.0, beta0 = c0, ess = 0.0;
    } else {
      beta0 = std::sqrt(c0 * c0 + tail);
      if (c0 >= 0.0) beta0 = -beta0;
      ess = a[2][0] / (c0 - beta0);
      h0 = (beta0 - c0) / beta0;
    }
  }
  const double v0 = 1.0, v1 = ess;
  // hc = selfadjoint(lower 2x2 block) * (h0 v), in Eigen's scalar symv order
  double hc0 = 0.0, hc1 = 0.0;
  {
    double t1 = h0 * v0, t2 = 0.0;
    hc0 += a[1][1] * t1;
    hc1 += a[2][1] * t1;
    t2 += a[2][1] * v1;
    hc0 += h0 * t2;
    t1 = h0 * v1;
    hc1 += a[2][2] * t1;
    hc1 += h0 * 0.0;
  }
  const double dot = hc0 * v0 + hc1 * v1;
  const double sc = (h0 * -0.5) * dot;
  hc0 += sc * v0, hc1 += sc * v1;
  // rank-2 update of the lower block with alpha = -1
  a[1][1] += (-1.0 * v0) * hc0 + (-1.0 * hc0) * v0;
  a[2][1] += (-1.0 * v0) * hc1 + (-1.0 * hc0) * v1;
  a[2][2] += (-1.0 * v1) * hc1 + (-1.0 * hc1) * v1;
  diag[0] = a[0][0], diag[1] = a[1][1], diag[2] = a[2][2];
  sub[0] = beta0, sub[1] = a[2][1];  // step 1's Householder of a length-1 vector is the identity
  // Q = H0 formed in place (columns: q[.][c])
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) q[r][c] = r == c ? 1.0 : 0.0;
  if (h0 != 0.0) {
    const double te = h0 * ess;
    q[1][1] = 1.0 - h0 * 1.0;
    q[1][2] = 0.0 - h0 * (ess * 1.0 + 0.0);
    q[2][1] = 0.0 - te * 1.0;
    q[2][2] = 1.0 - te * (ess * 1.0 + 0.0);
  }
}

// Eigen's computeFromTridiagonal_impl on the 3x3 tridiagonal (diag, sub), accumulating the rotations into q; false
// when it gives up after 30 * 3 steps (Eigen then leaves the eigenvalues unsorted).
bool tridiagonal_qr3(double diag[3], double sub[2], double q[3][3]) {
  const double zero_tol = DBL_MIN, precision = 2.0 * DBL_EPSILON;
  int64_t end = 2, start = 0, iter = 0;
  while (end > 0) {
    for (int64_t i = start; i < end; ++i)
      if (std::fabs(sub[i]) <= (std::fabs(diag[i]) + std::fabs(diag[i + 1])) * precision ||
          std::fabs(sub[i]) <= zero_tol)
        sub[i] = 0.0;
    while (end > 0 && sub[end - 1] == 0.0) end--;
    if (end <= 0) break;
    if (++iter > 30 * 3) return false;
    start = end - 1;
    while (start > 0 && sub[start - 1] != 0.0) start--;
    // tridiagonal_qr_step
    const double td = (diag[end - 1] - diag[end]) * 0.5, e = sub[end - 1];
    double mu = diag[end];
    if (td == 0.0) {
      mu -= std::fabs(e);
    } else {
      const double e2 = e * e, h = eigen_hypot(td, e);
      if (e2 == 0.0)
        mu -= (e / (td + (td > 0.0 ? 1.0 : -1.0))) * (e / h);
      else
        mu -= e2 / (td + (td > 0.0 ? h : -h));
    }
    double x = diag[start] - mu, z = sub[start];
    for (int64_t k = start; k < end; ++k) {
      double c, s;
      make_givens(x, z, c, s);
      const double sdk = s * diag[k] + c * sub[k];
      const double dkp1 = s * sub[k] + c * diag[k + 1];
      diag[k] = c * (c * diag[k] - s * sub[k]) - s * (c * sub[k] - s * diag[k + 1]);
      diag[k + 1] = s * sdk + c * dkp1;
      sub[k] = c * sdk - s * dkp1;
      if (k > start) sub[k - 1] = c * sub[k - 1] - s * z;
      x = sub[k];
      if (k < end - 1) {
        z = -s * sub[k + 1];
        sub[k + 1] = c * sub[k + 1];
      }
      for (int r = 0; r < 3; ++r) {  // Q <- Q G (applyOnTheRight with the transposed rotation)
        const double xi = q[r][k], yi = q[r][k + 1];
        q[r][k] = c * xi + (-s) * yi;
        q[r][k + 1] = -(-s) * xi + c * yi;
      }
    }
  }
  return true;
}

// Eigenvectors of a symmetric 3x3 matrix as Eigen 3.3's SelfAdjointEigenSolver<MatrixXd> computes them: the two
// steps above, then the eigenvalues sorted ascending by selection (the first smallest; equal ones keep their order).
// vec[row][col]; column 0 has the smallest eigenvalue.
void eigen_sym3(const double a_in[3][3], double vec[3][3]) {
  double diag[3], sub[2], q[3][3];
  tridiagonalise3(a_in, diag, sub, q);
  const bool ok = tridiagonal_qr3(diag, sub, q);
  if (ok)
    for (int i = 0; i < 2; ++i) {
      int k = i;
      for (int j = i + 1; j < 3; ++j)
        if (diag[j] < diag[k]) k = j;
      if (k != i) {
        std::swap(diag[i], diag[k]);
        for (int r = 0; r < 3; ++r) std::swap(q[r][i], q[r][k]);
      }
    }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) vec[r][c] = q[r][c];
}

// Eigen 3.3's sum of a dynamic-size expression (redux, SSE2 packets of 2 doubles): two packet accumulators over
// groups of four, merged, one more packet, then the lanes added and the odd last term. An ill-conditioned quadric fit
// amplifies the last bits of these sums into the printed figures, so they are summed in exactly this order.
template <typename F>
double eigen_sum(int64_t n, const F& x) {
  if (n == 0) return 0.0;
  const int64_t size2 = (n / 4) * 4, size1 = (n / 2) * 2;
  if (size1 == 0) return x(0);
  double a0 = x(0), a1 = x(1);
  if (size1 > 2) {
    double b0 = x(2), b1 = x(3);
    for (int64_t i = 4; i < size2; i += 4) a0 = a0 + x(i), a1 = a1 + x(i + 1), b0 = b0 + x(i + 2), b1 = b1 + x(i + 3);
    a0 = a0 + b0, a1 = a1 + b1;
    if (size1 > size2) a0 = a0 + x(size2), a1 = a1 + x(size2 + 1);
  }
  double res = a0 + a1;
  for (int64_t i = size1; i < n; ++i) res = res + x(i);
  return res;
}

// Eigen 3.3's row-major matrix-vector kernel for one output (SSE2): the terms before the right-hand side's first
// 16-byte boundary, then two lanes over aligned pairs, then the rest. `start` is the start of the products from that
// boundary (0 or 1); `vectorised` false when the kernel falls back to plain sums.
template <typename F>
double eigen_gemv_dot(int64_t depth, int64_t start, bool vectorised, const F& x) {
  if (!vectorised) start = 0;
  const int64_t aligned = vectorised ? start + ((depth - start) & ~int64_t(1)) : 0;
  double t = 0.0;
  for (int64_t j = 0; j < start; ++j) t += x(j);
  if (aligned > start) {
    double l0 = 0.0, l1 = 0.0;
    for (int64_t j = start; j < aligned; j += 2) l0 = x(j) + l0, l1 = x(j + 1) + l1;
    t += l0 + l1;
  }
  for (int64_t j = aligned; j < depth; ++j) t += x(j);
  return t;
}

// Applies step k's Householder reflection (essential part below A(k, k), coefficient tau) to the columns right of k,
// as Eigen's applyHouseholderOnTheLeft: tmp = essential^T * bottom through Eigen's gemv, whose alignment tests use the
// element offsets from A's 16-byte aligned start.
void householder_right_columns(std::vector<double>& A, int64_t m, int64_t k, double tau) {
  const int64_t cols = 6, r = m - k - 1;
  if (r == 0 || tau == 0.0) return;
  const double* ck = A.data() + k * m;
  const int64_t ncols = cols - k - 1, ess_off = k * m + k + 1, lhs_off = (k + 1) * m + k + 1;
  const int64_t start = std::min<int64_t>(r, ess_off % 2);
  const bool vectorised = !(std::min<int64_t>(r, lhs_off % 2) == r || std::min<int64_t>(ncols, ess_off % 2) == ncols);
  for (int64_t j = k + 1; j < cols; ++j) {
    double* cj = A.data() + j * m;
    double tmp = eigen_gemv_dot(r, start, vectorised, [&](int64_t i) { return ck[k + 1 + i] * cj[k + 1 + i]; });
    tmp += cj[k];
    cj[k] -= tau * tmp;
    for (int64_t i = k + 1; i < m; ++i) cj[i] -= tmp * (tau * ck[i]);
  }
}

// Eigen 3.3's ColPivHouseholderQR of an (m, 6) column-major A, in place: column pivoting on the running column norms
// (LAPACK's downdate), rank = the pivots met before a column's norm fell below (max norm * eps)^2 * (m - k) / m.
struct ColPivQR {
  int64_t nonzero = 0;
  double hc[6] = {0, 0, 0, 0, 0, 0};
  int perm[6] = {0, 1, 2, 3, 4, 5};
};

ColPivQR colpiv_decompose(std::vector<double>& A, int64_t m) {
  const int cols = 6;
  const int64_t size = std::min<int64_t>(m, cols);
  const double eps = DBL_EPSILON;
  auto col = [&](int64_t j) { return A.data() + j * m; };
  auto norm = [&](int64_t j, int64_t from) {
    const double* c = col(j) + from;
    return std::sqrt(eigen_sum(m - from, [&](int64_t i) { return c[i] * c[i]; }));
  };
  ColPivQR qr;
  double nu[6], nd[6];
  int transp[6];
  for (int j = 0; j < cols; ++j) nu[j] = nd[j] = norm(j, 0);
  double maxn = nu[0];
  for (int j = 1; j < cols; ++j) maxn = std::max(maxn, nu[j]);
  const double th = (maxn * eps) * (maxn * eps) / static_cast<double>(m), downdate = std::sqrt(eps);
  qr.nonzero = size;
  for (int64_t k = 0; k < size; ++k) {
    int64_t bi = k;
    for (int64_t j = bi + 1; j < cols; ++j)
      if (nu[j] > nu[bi]) bi = j;
    if (qr.nonzero == size && nu[bi] * nu[bi] < th * static_cast<double>(m - k)) qr.nonzero = k;
    transp[k] = static_cast<int>(bi);
    if (bi != k) {
      std::swap_ranges(col(k), col(k) + m, col(bi));
      std::swap(nu[k], nu[bi]);
      std::swap(nd[k], nd[bi]);
    }
    double* ck = col(k);
    const double c0 = ck[k];
    const int64_t r = m - k - 1;  // the Householder vector's tail (its "essential part")
    const double tail = r == 0 ? 0.0 : eigen_sum(r, [&](int64_t i) { return ck[k + 1 + i] * ck[k + 1 + i]; });
    double tau, beta;
    if (tail <= DBL_MIN) {
      tau = 0.0, beta = c0;
      for (int64_t i = k + 1; i < m; ++i) ck[i] = 0.0;
    } else {
      beta = std::sqrt(c0 * c0 + tail);
      if (c0 >= 0.0) beta = -beta;
      for (int64_t i = k + 1; i < m; ++i) ck[i] = ck[i] / (c0 - beta);
      tau = (beta - c0) / beta;
    }
    qr.hc[k] = tau;
    ck[k] = beta;
    householder_right_columns(A, m, k, tau);
    for (int64_t j = k + 1; j < cols; ++j) {
      if (nu[j] == 0.0) continue;
      double t = std::fabs(col(j)[k]) / nu[j];
      t = (1.0 + t) * (1.0 - t);
      if (t < 0.0) t = 0.0;
      const double ratio = nu[j] / nd[j];
      if (t * (ratio * ratio) <= downdate) {
        nd[j] = norm(j, k + 1);
        nu[j] = nd[j];
      } else {
        nu[j] *= std::sqrt(t);
      }
    }
  }
  for (int64_t k = 0; k < size; ++k) std::swap(qr.perm[k], qr.perm[transp[k]]);
  return qr;
}

// ColPivHouseholderQR::solve: Q^T b with the first `nonzero` reflections, back substitution on R's leading block
// (column-oriented, as Eigen's), zeros for the columns past the rank (the basic solution), un-permuted.
void colpiv_solve(const std::vector<double>& A, int64_t m, const ColPivQR& qr, std::vector<double>& b, double out[6]) {
  auto col = [&](int64_t j) { return A.data() + j * m; };
  for (int j = 0; j < 6; ++j) out[j] = 0.0;
  if (qr.nonzero == 0) return;
  for (int64_t k = 0; k < qr.nonzero; ++k) {  // b <- H_{k} ... H_0 b
    const double* ck = col(k);
    if (m - k == 1 || qr.hc[k] == 0.0) continue;
    double tmp = eigen_sum(m - k - 1, [&](int64_t i) { return ck[k + 1 + i] * b[k + 1 + i]; });
    tmp += b[k];
    b[k] -= qr.hc[k] * tmp;
    for (int64_t i = k + 1; i < m; ++i) b[i] -= tmp * (qr.hc[k] * ck[i]);
  }
  for (int64_t i = qr.nonzero - 1; i >= 0; --i) {
    if (b[i] == 0.0) continue;
    b[i] /= col(i)[i];
    for (int64_t r = 0; r < i; ++r) b[r] -= b[i] * col(i)[r];
  }
  for (int64_t i = 0; i < qr.nonzero; ++i) out[qr.perm[i]] = b[i];
}

struct FitScratch {
  std::vector<double> A, b;
};

// PCQM's computeProjectionAndCurvature: the quadric z = f(x, y) in the neighbours' principal frame around `o`.
// Returns the mean curvature at o; `proj` gets o moved along the normal to the quadric.
double fit_quadric(const double* o, const double* pts, const int64_t* ind, int64_t m, double proj[3],
                   FitScratch& s) {
  // No neighbour: PCQM's covariance is 0/0 and its eigenvectors NaN, but the empty system's solution is 0, so H = 0
  // (proj is only asked of the k nearest, never empty). Returned at once rather than iterating on NaN.
  if (m == 0) return 0.0;
  double mu[3] = {0, 0, 0}, M[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  for (int64_t i = 0; i < m; ++i) {
    const double* p = pts + 3 * ind[i];
    for (int a = 0; a < 3; ++a) {
      mu[a] = mu[a] + p[a];
      for (int c = 0; c < 3; ++c) M[a][c] = M[a][c] + p[a] * p[c];
    }
  }
  const double nn = static_cast<double>(m);
  for (int a = 0; a < 3; ++a) mu[a] = mu[a] / nn;
  for (int a = 0; a < 3; ++a)
    for (int c = 0; c < 3; ++c) M[a][c] = 1. / nn * M[a][c] - mu[a] * mu[c];
  double V[3][3];
  eigen_sym3(M, V);
  const double t1[3] = {V[0][2], V[1][2], V[2][2]}, t2[3] = {V[0][1], V[1][1], V[2][1]},
               n[3] = {V[0][0], V[1][0], V[2][0]};
  s.A.assign(static_cast<size_t>(6 * m), 0.0);
  s.b.assign(static_cast<size_t>(m), 0.0);
  for (int64_t i = 0; i < m; ++i) {
    const double* p = pts + 3 * ind[i];
    const double v[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
    const double x = v[0] * t1[0] + v[1] * t1[1] + v[2] * t1[2];
    const double y = v[0] * t2[0] + v[1] * t2[1] + v[2] * t2[2];
    const double z = v[0] * n[0] + v[1] * n[1] + v[2] * n[2];
    s.A[i] = x * x, s.A[m + i] = y * y, s.A[2 * m + i] = x * y;
    s.A[3 * m + i] = x, s.A[4 * m + i] = y, s.A[5 * m + i] = 1.0;
    s.b[i] = z;
  }
  double c[6];
  const ColPivQR qr = colpiv_decompose(s.A, m);
  colpiv_solve(s.A, m, qr, s.b, c);
  for (int a = 0; a < 3; ++a) proj[a] = o[a] + c[5] * n[a];
  const double fxx = 2 * c[0], fyy = 2 * c[1], fxy = c[2], fx = c[3], fy = c[4];
  return 0.5 * ((1 + fx * fx) * fyy + (1 + fy * fy) * fxx - 2 * fxy * fx * fy) / std::pow(1 + fx * fx + fy * fy, 1.5);
}

double distance(const double* a, const double* b) {
  return std::sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
}

// What PCQM's first loop leaves per point of the registered cloud: the projection on the reference (or the nearest
// reference point, if nearer), both curvatures times max_dim, and the lightness of the nearest reference point.
struct Projected {
  std::vector<double> proj, curv_ref, curv_reg, l_proj;
};

Projected project_and_curve(const Tree& t_ref, const Tree& t_reg, const double* lf, double radius, double max_dim,
                            int64_t knn) {
  const int64_t n = t_reg.n;
  Projected out{std::vector<double>(3 * n), std::vector<double>(n), std::vector<double>(n), std::vector<double>(n)};
  tmm::chunked_for(n, GRAIN, [&](int64_t begin, int64_t end) {
    std::vector<int64_t> ki(knn), ind;
    std::vector<double> kd(knn);
    std::vector<std::pair<int64_t, double>> hits;
    FitScratch s;
    for (int64_t i = begin; i < end; ++i) {
      const double* o = t_reg.p + 3 * i;
      std::fill(ki.begin(), ki.end(), 0);  // PCQM's zero-initialised index vector: missing neighbours = point 0
      Knn res(knn, ki.data(), kd.data());
      t_ref.find(res, o);
      double p[3], dummy[3], h[2];
      fit_quadric(o, t_ref.p, ki.data(), knn, p, s);
      const Tree* trees[2] = {&t_ref, &t_reg};
      for (int w = 0; w < 2; ++w) {
        radius_search(*trees[w], o, radius * radius, true, hits);
        ind.resize(hits.size());
        for (size_t j = 0; j < hits.size(); ++j) ind[j] = hits[j].first;
        h[w] = fit_quadric(o, trees[w]->p, ind.data(), static_cast<int64_t>(ind.size()), dummy, s);
      }
      out.curv_ref[i] = std::fabs(h[0]) * max_dim;
      out.curv_reg[i] = std::fabs(h[1]) * max_dim;
      const double* near = t_ref.p + 3 * ki[0];
      const bool keep = distance(o, p) <= distance(o, near);
      for (int a = 0; a < 3; ++a) out.proj[3 * i + a] = keep ? p[a] : near[a];
      out.l_proj[i] = lf[ki[0]];
    }
  });
  return out;
}

// PCQM's compute_statistics for point i: Gaussian weights over its registered neighbours within r2 (of their
// distance, and of their projections' distance), then the curvature structure, lightness and lightness structure
// features (PCQM's "me" = registered, "proj" = reference side), written to f[0..2].
void pool_features(const Tree& t_reg, const Projected& pr, const double* lr, double r2, double var, int64_t i,
                   std::vector<std::pair<int64_t, double>>& hits, std::vector<double>& wa, std::vector<double>& wb,
                   double* f) {
  radius_search(t_reg, t_reg.p + 3 * i, r2, false, hits);
  const size_t k = hits.size();
  wa.resize(k), wb.resize(k);
  double sa = 0.0, sb = 0.0;
  for (size_t j = 0; j < k; ++j) {
    const double da = std::sqrt(hits[j].second);
    const double db = distance(&pr.proj[3 * i], &pr.proj[3 * hits[j].first]);
    wa[j] = 1.0 / var / std::sqrt(2 * 3.141592) * std::exp(-(da * da) / 2.0 / var / var);
    wb[j] = 1.0 / var / std::sqrt(2 * 3.141592) * std::exp(-(db * db) / 2.0 / var / var);
    sa += wa[j], sb += wb[j];
  }
  const double *ca = pr.curv_reg.data(), *cb = pr.curv_ref.data(), *lb = pr.l_proj.data();
  double mu_a = 0.0, mu_b = 0.0, la = 0.0, lm = 0.0, ua = 0.0, ub = 0.0, cnt = 0.0;
  for (size_t j = 0; j < k; ++j) {
    const int64_t q = hits[j].first;
    mu_a += ca[q] * wa[j], mu_b += cb[q] * wb[j];
    la += lr[q] * wa[j], lm += lb[q] * wb[j];
    ua += lr[q], ub += lb[q];
    cnt += 1.0;
  }
  mu_a /= sa, mu_b /= sb, la /= sa, lm /= sb, ua /= cnt, ub /= cnt;
  double va = 0.0, vb = 0.0, cov = 0.0, sda = 0.0, sdb = 0.0, ccov = 0.0;
  for (size_t j = 0; j < k; ++j) {
    const int64_t q = hits[j].first;
    const double ea = std::fabs(ca[q]) - mu_a, eb = std::fabs(cb[q]) - mu_b;
    va += (ea * ea) * wa[j];  // pow(x, 2.0): GCC emits x * x, the same correctly rounded square
    vb += (eb * eb) * wb[j];
    cov += (ea * eb) * wa[j];
    sda += (lr[q] - ua) * (lr[q] - ua);
    sdb += (lb[q] - ub) * (lb[q] - ub);
    ccov += (lr[q] - ua) * (lb[q] - ub);
  }
  const double sd_a = std::sqrt(va / sa), sd_b = std::sqrt(vb / sb);
  cov = cov / sa;
  double structure = std::fabs(sd_a * sd_b - cov) / ((sd_a * sd_b) + 1.0);
  if (structure > 1.0) structure = 1.0;
  f[0] = structure;
  f[1] = 1.0 / (0.002 * (la - lm) * (la - lm) + 1.0);
  sda /= cnt, sdb /= cnt;
  if (sda < 0) sda = 0.0;
  if (sdb < 0) sdb = 0.0;
  ccov /= cnt;
  f[2] = (ccov + 0.1) / (std::sqrt(sda) * std::sqrt(sdb) + 0.1);
}

}  // namespace

// PCQM's two loops for every point of `reg`. reg: (N, 3) float64, ref: (M, 3) float64, l_reg: (N,), l_ref: (M,) the
// points' LAB2000HL lightness. Returns (fields (N, 5): geometric structure, colour lightness, colour structure,
// |H| * max_dim on the reference, |K| * max_dim on the registered cloud; sums (3,): the first three fields summed
// in point order, as PCQM accumulates them).
std::vector<torch::Tensor> pcqm_fields(torch::Tensor reg, torch::Tensor ref, torch::Tensor l_reg, torch::Tensor l_ref,
                                       double radius, double max_dim, int64_t knn, double factor) {
  TORCH_CHECK(reg.dtype() == torch::kFloat64 && ref.dtype() == torch::kFloat64, "pcqm: float64 points expected");
  TORCH_CHECK(l_reg.dtype() == torch::kFloat64 && l_ref.dtype() == torch::kFloat64, "pcqm: float64 lightness expected");
  reg = reg.contiguous(), ref = ref.contiguous(), l_reg = l_reg.contiguous(), l_ref = l_ref.contiguous();
  const int64_t n = reg.size(0), m = ref.size(0);
  TORCH_CHECK(n > 0 && m > 0 && knn > 0, "pcqm: empty cloud or knn < 1");
  TORCH_CHECK(l_reg.numel() == n && l_ref.numel() == m, "pcqm: one lightness per point expected");
  Tree t_ref, t_reg;
  t_ref.build(ref.data_ptr<double>(), m);
  t_reg.build(reg.data_ptr<double>(), n);
  const Projected pr = project_and_curve(t_ref, t_reg, l_ref.data_ptr<double>(), radius, max_dim, knn);
  auto fields = torch::empty({n, 5}, torch::kFloat64);
  double* out = fields.data_ptr<double>();
  const double* lr = l_reg.data_ptr<double>();
  const double search = radius * factor, var = search / 2.0, r2 = std::pow(search, 2.0);
  tmm::chunked_for(n, GRAIN, [&](int64_t begin, int64_t end) {
    std::vector<std::pair<int64_t, double>> hits;
    std::vector<double> wa, wb;
    for (int64_t i = begin; i < end; ++i) {
      pool_features(t_reg, pr, lr, r2, var, i, hits, wa, wb, out + 5 * i);
      out[5 * i + 3] = pr.curv_ref[i];
      out[5 * i + 4] = pr.curv_reg[i];
    }
  });
  auto sums = torch::zeros({3}, torch::kFloat64);
  double* s = sums.data_ptr<double>();
  for (int64_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) s[c] += out[5 * i + c];
  return {fields, sums};
}

PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) {
  m.def("pcqm_fields", &pcqm_fields, "PCQM's per-point features (curvature structure, lightness terms)");
}
