// Registration energy of an embedded deformation graph and its gradient to the node rotations and translations, in
// one pass (torchmeshmetric.registration.energies.fused_energy): the deformed data vertices, the robust data terms
// to fixed target faces (point-to-point + point-to-plane), the reverse term of fixed target samples to deformed
// source faces, Sumner's E_reg, and their gradients by the chain rule (the closest point's own motion does not
// contribute: the gradient of the squared distance to a closest point is 2 (p - q), the envelope theorem).
#include <torch/extension.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "triangle.h"

namespace {

// Geman-McClure rho(x) = s2 x / (s2 + x) and its derivative s2^2 / (s2 + x)^2 on a squared residual x.
template <typename T>
inline T gm(T x, T s2, T& d) {
  const T den = s2 + x;
  d = (s2 * s2) / (den * den);
  return s2 * x / den;
}

// Vertices per thread chunk of the full-mesh deformation (below this, one thread: a parallel region costs more).
constexpr int64_t DEFORM_GRAIN = 4096;

// x = sum_k w_k [R_k (v - g_k) + g_k + t_k] for one vertex.
template <typename T>
inline void deform_one(const T* R, const T* t, const T* g, const T* v, const int64_t* vidx, const T* vw, int64_t K,
                       T* x) {
  T acc[3] = {0, 0, 0};
  for (int64_t k = 0; k < K; ++k) {
    const int64_t j = vidx[k];
    const T w = vw[k];
    const T d[3] = {v[0] - g[3 * j], v[1] - g[3 * j + 1], v[2] - g[3 * j + 2]};
    const T* Rj = R + 9 * j;
    for (int a = 0; a < 3; ++a)
      acc[a] += w * (Rj[3 * a] * d[0] + Rj[3 * a + 1] * d[1] + Rj[3 * a + 2] * d[2] + g[3 * j + a] + t[3 * j + a]);
  }
  for (int a = 0; a < 3; ++a) x[a] = acc[a];
}

// The skinned vertices of a deformation graph (node rotations R (N, 3, 3), translations t and positions g (N, 3);
// rest positions (I, 3), K node indices and weights per vertex), read from contiguous tensors.
template <typename T>
struct Skinning {
  const T* R;
  const T* t;
  const T* g;
  const T* rest;
  const int64_t* vidx;
  const T* vw;
  int64_t I, K;

  Skinning(const torch::Tensor& Rt, const torch::Tensor& tt, const torch::Tensor& gt_, const torch::Tensor& rest_t,
           const torch::Tensor& vidx_t, const torch::Tensor& vw_t)
      : R(Rt.data_ptr<T>()), t(tt.data_ptr<T>()), g(gt_.data_ptr<T>()), rest(rest_t.data_ptr<T>()),
        vidx(vidx_t.data_ptr<int64_t>()), vw(vw_t.data_ptr<T>()), I(rest_t.size(0)), K(vidx_t.size(1)) {}

  // Deformed position of vertex i into x[0..2].
  void deform(int64_t i, T* x) const { deform_one(R, t, g, rest + 3 * i, vidx + i * K, vw + i * K, K, x); }
};

// [u]x, the cross-product matrix, row major.
inline void skew(const double* u, double* m) {
  m[0] = 0; m[1] = -u[2]; m[2] = u[1];
  m[3] = u[2]; m[4] = 0; m[5] = -u[0];
  m[6] = -u[1]; m[7] = u[0]; m[8] = 0;
}

// dL/dv for R = exp([v]x) given G = dL/dR (row major), in double whatever T. Gallego & Yezzi 2015:
// dR/dv_i = (v_i [v]x + [v x ((I - R) e_i)]x) R / |v|^2; near v = 0 (|v|^2 <= 1e-8, where that quotient loses
// digits) the derivative of the second-order series I + [v]x + [v]x^2 / 2: [e_i]x + ([e_i]x [v]x + [v]x [e_i]x) / 2.
template <typename T>
inline void rotation_vjp(const T* v_in, const T* R_in, const T* G_in, T* out) {
  const double v[3] = {double(v_in[0]), double(v_in[1]), double(v_in[2])};
  double R[9], G[9];
  for (int k = 0; k < 9; ++k) {
    R[k] = double(R_in[k]);
    G[k] = double(G_in[k]);
  }
  const double th2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  double V[9];
  skew(v, V);
  for (int i = 0; i < 3; ++i) {
    double D[9];
    double e[3] = {0, 0, 0};
    e[i] = 1;
    double E[9];
    skew(e, E);
    if (th2 > 1e-8) {
      double c[3];  // (I - R) e_i
      for (int a = 0; a < 3; ++a) c[a] = e[a] - R[3 * a + i];
      const double u[3] = {v[1] * c[2] - v[2] * c[1], v[2] * c[0] - v[0] * c[2], v[0] * c[1] - v[1] * c[0]};
      double U[9], M[9];
      skew(u, U);
      for (int k = 0; k < 9; ++k) M[k] = (v[i] * V[k] + U[k]) / th2;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) D[3 * a + b] = M[3 * a] * R[b] + M[3 * a + 1] * R[3 + b] + M[3 * a + 2] * R[6 + b];
    } else {
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
          double ev = 0, ve = 0;
          for (int k = 0; k < 3; ++k) {
            ev += E[3 * a + k] * V[3 * k + b];
            ve += V[3 * a + k] * E[3 * k + b];
          }
          D[3 * a + b] = E[3 * a + b] + 0.5 * (ev + ve);
        }
    }
    double s = 0;
    for (int k = 0; k < 9; ++k) s += G[k] * D[k];
    out[i] = T(s);
  }
}

template <typename T>
std::vector<torch::Tensor> energy_impl(const torch::Tensor& axis_t, const torch::Tensor& Rt, const torch::Tensor& tt, const torch::Tensor& gt_,
                                       const torch::Tensor& rest_t, const torch::Tensor& vidx_t,
                                       const torch::Tensor& vw_t, const torch::Tensor& data_idx_t,
                                       const torch::Tensor& data_tri_t, const torch::Tensor& data_n_t,
                                       const torch::Tensor& data_w_t, const torch::Tensor& samples_t,
                                       const torch::Tensor& rev_faces_t, const torch::Tensor& rev_w_t,
                                       const torch::Tensor& edges_t, std::vector<double> s) {
  const T sigma = T(s[0]), plane_w = T(s[1]), point_w = T(s[2]), rev_w = T(s[3]), data_scale = T(s[4]),
          reg_w = T(s[5]);
  const T s2 = sigma * sigma;
  const Skinning<T> skin(Rt, tt, gt_, rest_t, vidx_t, vw_t);
  const int64_t N = Rt.size(0), I = skin.I, K = skin.K, S = data_idx_t.size(0), Q = samples_t.size(0),
                E = edges_t.size(0);
  const T *R = skin.R, *t = skin.t, *g = skin.g, *rest = skin.rest, *vw = skin.vw;
  const int64_t* vidx = skin.vidx;
  // 1. Deformed positions of the needed vertices.
  std::vector<T> x(3 * I);
  for (int64_t i = 0; i < I; ++i) skin.deform(i, &x[3 * i]);
  std::vector<T> gx(3 * I, T(0));
  T loss = 0;
  // 2. Data term: deformed data vertices to fixed target faces.
  const int64_t* di = data_idx_t.data_ptr<int64_t>();
  const T* dtri = data_tri_t.data_ptr<T>();
  const T* dn = data_n_t.data_ptr<T>();
  const T* dw = data_w_t.data_ptr<T>();
  T wsum = 0;
  for (int64_t k = 0; k < S; ++k) wsum += dw[k];
  const T dnorm = data_scale / std::max(wsum, T(1));
  for (int64_t k = 0; k < S; ++k) {
    if (dw[k] == 0) continue;
    const T* p = &x[3 * di[k]];
    const T* a = dtri + 9 * k;
    T bary[3], q[3];
    const T sq = tmm::closest_on_face(a, a + 3, a + 6, p, bary, q);
    T d1;
    T e = point_w * gm(sq, s2, d1);
    T gp[3];
    for (int c = 0; c < 3; ++c) gp[c] = point_w * d1 * T(2) * (p[c] - q[c]);
    if (plane_w != 0) {
      const T* n = dn + 3 * k;
      const T dist = (p[0] - a[0]) * n[0] + (p[1] - a[1]) * n[1] + (p[2] - a[2]) * n[2];
      T d2;
      e += plane_w * gm(dist * dist, s2, d2);
      for (int c = 0; c < 3; ++c) gp[c] += plane_w * d2 * T(2) * dist * n[c];
    }
    const T f = dw[k] * dnorm;
    loss += f * e;
    for (int c = 0; c < 3; ++c) gx[3 * di[k] + c] += f * gp[c];
  }
  // 3. Reverse term: fixed target samples to deformed source faces (point-to-point).
  const T* smp = samples_t.data_ptr<T>();
  const int64_t* rf = rev_faces_t.data_ptr<int64_t>();
  const T* rw = rev_w_t.data_ptr<T>();
  if (rev_w != 0 && Q > 0) {
    T rsum = 0;
    for (int64_t k = 0; k < Q; ++k) rsum += rw[k];
    const T rnorm = rev_w * data_scale / std::max(rsum, T(1));
    for (int64_t k = 0; k < Q; ++k) {
      if (rw[k] == 0) continue;
      const T* p = smp + 3 * k;
      const int64_t ia = rf[3 * k], ib = rf[3 * k + 1], ic = rf[3 * k + 2];
      T bary[3], q[3];
      const T sq = tmm::closest_on_face(&x[3 * ia], &x[3 * ib], &x[3 * ic], p, bary, q);
      T d1;
      const T e = gm(sq, s2, d1);
      const T f = rw[k] * rnorm;
      loss += f * e;
      for (int c = 0; c < 3; ++c) {
        const T gq = -f * d1 * T(2) * (p[c] - q[c]);  // d/dq; q = b0 a + b1 b + b2 c
        gx[3 * ia + c] += bary[0] * gq;
        gx[3 * ib + c] += bary[1] * gq;
        gx[3 * ic + c] += bary[2] * gq;
      }
    }
  }
  auto gR_t = torch::zeros({N, 3, 3}, Rt.options());
  auto gT_t = torch::zeros({N, 3}, tt.options());
  T* gR = gR_t.data_ptr<T>();
  T* gT = gT_t.data_ptr<T>();
  // 4. Back through the deformation: dx/dR_k = w_k (v - g_k)^T, dx/dt_k = w_k.
  for (int64_t i = 0; i < I; ++i) {
    const T* gi = &gx[3 * i];
    if (gi[0] == 0 && gi[1] == 0 && gi[2] == 0) continue;
    const T* v = rest + 3 * i;
    for (int64_t k = 0; k < K; ++k) {
      const int64_t j = vidx[i * K + k];
      const T w = vw[i * K + k];
      const T d[3] = {v[0] - g[3 * j], v[1] - g[3 * j + 1], v[2] - g[3 * j + 2]};
      for (int a = 0; a < 3; ++a) {
        const T wg = w * gi[a];
        gT[3 * j + a] += wg;
        for (int b = 0; b < 3; ++b) gR[9 * j + 3 * a + b] += wg * d[b];
      }
    }
  }
  // 5. Sumner's E_reg: mean |R_j (g_k - g_j) + g_j + t_j - (g_k + t_k)|^2 / mean |g_k - g_j|^2.
  if (E > 0 && reg_w != 0) {
    const int64_t* ed = edges_t.data_ptr<int64_t>();
    T den = 0;
    for (int64_t e = 0; e < E; ++e) {
      const int64_t j = ed[2 * e], k = ed[2 * e + 1];
      for (int c = 0; c < 3; ++c) {
        const T dg = g[3 * k + c] - g[3 * j + c];
        den += dg * dg;
      }
    }
    den = std::max(den / T(E), std::numeric_limits<T>::min());
    const T scale = reg_w / (T(E) * den);
    T reg = 0;
    for (int64_t e = 0; e < E; ++e) {
      const int64_t j = ed[2 * e], k = ed[2 * e + 1];
      const T dg[3] = {g[3 * k] - g[3 * j], g[3 * k + 1] - g[3 * j + 1], g[3 * k + 2] - g[3 * j + 2]};
      const T* Rj = R + 9 * j;
      T r[3];
      for (int a = 0; a < 3; ++a)
        r[a] = Rj[3 * a] * dg[0] + Rj[3 * a + 1] * dg[1] + Rj[3 * a + 2] * dg[2] + g[3 * j + a] + t[3 * j + a] -
               (g[3 * k + a] + t[3 * k + a]);
      reg += r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
      for (int a = 0; a < 3; ++a) {
        const T gr = T(2) * scale * r[a];
        gT[3 * j + a] += gr;
        gT[3 * k + a] -= gr;
        for (int b = 0; b < 3; ++b) gR[9 * j + 3 * a + b] += gr * dg[b];
      }
    }
    loss += scale * reg;
  }
  // 6. Back through the exponential map: dL/d(axis-angle) per node.
  auto gV_t = torch::empty({N, 3}, tt.options());
  const T* V = axis_t.data_ptr<T>();
  T* gV = gV_t.data_ptr<T>();
  for (int64_t j = 0; j < N; ++j) rotation_vjp(V + 3 * j, R + 9 * j, gR + 9 * j, gV + 3 * j);
  return {torch::full({}, loss, Rt.options()), gV_t, gT_t};
}

template <typename T>
torch::Tensor deform_impl(const torch::Tensor& Rt, const torch::Tensor& tt, const torch::Tensor& gt_,
                          const torch::Tensor& rest_t, const torch::Tensor& vidx_t, const torch::Tensor& vw_t) {
  const Skinning<T> skin(Rt, tt, gt_, rest_t, vidx_t, vw_t);
  torch::Tensor out = torch::empty({skin.I, 3}, rest_t.options());
  T* x = out.data_ptr<T>();
  at::parallel_for(0, skin.I, DEFORM_GRAIN, [&](int64_t s, int64_t e) {
    for (int64_t i = s; i < e; ++i) skin.deform(i, x + 3 * i);
  });
  return out;
}

// Farthest-point sampling from `start` until every point is within sqrt(s2) of a chosen one: the operations of
// deformation_graph.farthest_point_nodes (squared distances (dx*dx + dy*dy) + dz*dz, running minimum, first
// maximum), one thread: ~N passes over the points without a parallel region each.
template <typename T>
std::vector<int64_t> fps_impl(const T* p, int64_t n, int64_t start, double s2) {
  std::vector<int64_t> chosen{start};
  std::vector<T> dmin(n);
  auto sq = [p](int64_t i, int64_t j) {
    const T dx = p[3 * i] - p[3 * j], dy = p[3 * i + 1] - p[3 * j + 1], dz = p[3 * i + 2] - p[3 * j + 2];
    T s = dx * dx;
    s += dy * dy;
    s += dz * dz;
    return s;
  };
  for (int64_t i = 0; i < n; ++i) dmin[i] = sq(i, start);
  for (;;) {
    int64_t far = 0;
    for (int64_t i = 1; i < n; ++i)
      if (dmin[i] > dmin[far] || (std::isnan(dmin[i]) && !std::isnan(dmin[far]))) far = i;
    if (static_cast<double>(dmin[far]) <= s2) break;  // compared in double, as float(dmin[far]) <= s2
    chosen.push_back(far);
    for (int64_t i = 0; i < n; ++i) dmin[i] = std::min(dmin[i], sq(i, far));
  }
  return chosen;
}

}  // namespace

torch::Tensor farthest_point_sampling(torch::Tensor points, int64_t start, double spacing2) {
  TORCH_CHECK(points.is_contiguous() && points.device().is_cpu(), "farthest_point_sampling: contiguous CPU points");
  std::vector<int64_t> out;
  if (points.scalar_type() == torch::kFloat64)
    out = fps_impl<double>(points.data_ptr<double>(), points.size(0), start, spacing2);
  else {
    TORCH_CHECK(points.scalar_type() == torch::kFloat32, "farthest_point_sampling: float32 or float64 expected");
    out = fps_impl<float>(points.data_ptr<float>(), points.size(0), start, spacing2);
  }
  auto t = torch::empty({static_cast<int64_t>(out.size())}, torch::dtype(torch::kInt64));
  std::copy(out.begin(), out.end(), t.data_ptr<int64_t>());
  return t;
}

torch::Tensor deform_vertices(torch::Tensor R, torch::Tensor t, torch::Tensor g, torch::Tensor rest,
                              torch::Tensor vidx, torch::Tensor vw) {
  for (const auto* x : {&R, &t, &g, &rest, &vidx, &vw})
    TORCH_CHECK(x->is_contiguous() && x->device().is_cpu(), "deform_vertices: contiguous CPU tensors expected");
  if (R.scalar_type() == torch::kFloat64) return deform_impl<double>(R, t, g, rest, vidx, vw);
  TORCH_CHECK(R.scalar_type() == torch::kFloat32, "deform_vertices: float32 or float64 expected");
  return deform_impl<float>(R, t, g, rest, vidx, vw);
}

std::vector<torch::Tensor> deformation_energy(torch::Tensor axis, torch::Tensor R, torch::Tensor t, torch::Tensor g, torch::Tensor rest,
                                              torch::Tensor vidx, torch::Tensor vw, torch::Tensor data_idx,
                                              torch::Tensor data_tri, torch::Tensor data_n, torch::Tensor data_w,
                                              torch::Tensor samples, torch::Tensor rev_faces, torch::Tensor rev_w,
                                              torch::Tensor edges, std::vector<double> scalars) {
  TORCH_CHECK(scalars.size() == 6, "deformation_energy: 6 scalars expected");
  for (const auto* x : {&axis, &R, &t, &g, &rest, &vidx, &vw, &data_idx, &data_tri, &data_n, &data_w, &samples, &rev_faces,
                        &rev_w, &edges})
    TORCH_CHECK(x->is_contiguous() && x->device().is_cpu(), "deformation_energy: contiguous CPU tensors expected");
  if (R.scalar_type() == torch::kFloat64)
    return energy_impl<double>(axis, R, t, g, rest, vidx, vw, data_idx, data_tri, data_n, data_w, samples, rev_faces, rev_w,
                               edges, scalars);
  TORCH_CHECK(R.scalar_type() == torch::kFloat32, "deformation_energy: float32 or float64 expected");
  return energy_impl<float>(axis, R, t, g, rest, vidx, vw, data_idx, data_tri, data_n, data_w, samples, rev_faces, rev_w,
                            edges, scalars);
}
