// Registration energy of an embedded deformation graph and its gradient to the node rotations and translations, in
// one pass (torchmeshmetric.registration.energies.fused_energy): the deformed data vertices, the robust data terms
// to fixed target faces (point-to-point + point-to-plane), the reverse term of fixed target samples to deformed
// source faces, Sumner's E_reg, and their gradients by the chain rule (the closest point's own motion does not
// contribute: the gradient of the squared distance to a closest point is 2 (p - q), the envelope theorem).
#include <torch/extension.h>
#include <ATen/Parallel.h>

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

// Rows per block of the per-thread accumulation; below two blocks the work runs on the calling thread.
constexpr int64_t ENERGY_BLOCK = 2048;

template <typename T>
std::vector<torch::Tensor> energy_impl(const torch::Tensor& Rt, const torch::Tensor& tt, const torch::Tensor& gt_,
                                       const torch::Tensor& rest_t, const torch::Tensor& vidx_t,
                                       const torch::Tensor& vw_t, const torch::Tensor& data_idx_t,
                                       const torch::Tensor& data_tri_t, const torch::Tensor& data_n_t,
                                       const torch::Tensor& data_w_t, const torch::Tensor& samples_t,
                                       const torch::Tensor& rev_faces_t, const torch::Tensor& rev_w_t,
                                       const torch::Tensor& edges_t, std::vector<double> s) {
  const T sigma = T(s[0]), plane_w = T(s[1]), point_w = T(s[2]), rev_w = T(s[3]), data_scale = T(s[4]),
          reg_w = T(s[5]);
  const T s2 = sigma * sigma;
  const int64_t N = Rt.size(0), I = rest_t.size(0), K = vidx_t.size(1), S = data_idx_t.size(0),
                Q = samples_t.size(0), E = edges_t.size(0);
  const T* R = Rt.data_ptr<T>();
  const T* t = tt.data_ptr<T>();
  const T* g = gt_.data_ptr<T>();
  const T* rest = rest_t.data_ptr<T>();
  const int64_t* vidx = vidx_t.data_ptr<int64_t>();
  const T* vw = vw_t.data_ptr<T>();
  // 1. Deformed positions of the needed vertices: x = sum_k w_k [R_k (v - g_k) + g_k + t_k].
  std::vector<T> x(3 * I);
  for (int64_t i = 0; i < I; ++i) {
    T acc[3] = {0, 0, 0};
    const T* v = rest + 3 * i;
    for (int64_t k = 0; k < K; ++k) {
      const int64_t j = vidx[i * K + k];
      const T w = vw[i * K + k];
      const T d[3] = {v[0] - g[3 * j], v[1] - g[3 * j + 1], v[2] - g[3 * j + 2]};
      const T* Rj = R + 9 * j;
      for (int a = 0; a < 3; ++a)
        acc[a] += w * (Rj[3 * a] * d[0] + Rj[3 * a + 1] * d[1] + Rj[3 * a + 2] * d[2] + g[3 * j + a] + t[3 * j + a]);
    }
    for (int a = 0; a < 3; ++a) x[3 * i + a] = acc[a];
  }
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
  return {torch::full({}, loss, Rt.options()), gR_t, gT_t};
}

}  // namespace

std::vector<torch::Tensor> deformation_energy(torch::Tensor R, torch::Tensor t, torch::Tensor g, torch::Tensor rest,
                                              torch::Tensor vidx, torch::Tensor vw, torch::Tensor data_idx,
                                              torch::Tensor data_tri, torch::Tensor data_n, torch::Tensor data_w,
                                              torch::Tensor samples, torch::Tensor rev_faces, torch::Tensor rev_w,
                                              torch::Tensor edges, std::vector<double> scalars) {
  TORCH_CHECK(scalars.size() == 6, "deformation_energy: 6 scalars expected");
  for (const auto* x : {&R, &t, &g, &rest, &vidx, &vw, &data_idx, &data_tri, &data_n, &data_w, &samples, &rev_faces,
                        &rev_w, &edges})
    TORCH_CHECK(x->is_contiguous() && x->device().is_cpu(), "deformation_energy: contiguous CPU tensors expected");
  if (R.scalar_type() == torch::kFloat64)
    return energy_impl<double>(R, t, g, rest, vidx, vw, data_idx, data_tri, data_n, data_w, samples, rev_faces, rev_w,
                               edges, scalars);
  TORCH_CHECK(R.scalar_type() == torch::kFloat32, "deformation_energy: float32 or float64 expected");
  return energy_impl<float>(R, t, g, rest, vidx, vw, data_idx, data_tri, data_n, data_w, samples, rev_faces, rev_w,
                            edges, scalars);
}
