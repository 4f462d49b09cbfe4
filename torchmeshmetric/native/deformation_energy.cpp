// Registration energy of an embedded deformation graph and its gradient to the node rotations and translations, in
// one pass (torchmeshmetric.registration.energies): the node rotations (kornia's SO(3) exponential map), the deformed
// data vertices, the robust data terms to fixed target points and normals (point-to-point + point-to-plane), the
// reverse term of fixed target samples to fixed barycentric points of deformed source faces, Sumner's E_reg, and
// their gradients by the chain rule. Also the per-refresh geometry of the deformed source (every vertex, vertex normals, face
// normals) and the graph's farthest-point node sampling.
//
// Threads: each pass is a few phases over independent items (vertices, data points, target samples, edges, nodes),
// run in dynamic chunks on torch's pool (a preempted thread does not hold the others). Every sum keeps one fixed
// order whatever the thread count: per-item values are computed in parallel, then each vertex and each node gathers
// its contributions in the order of the serial loop (`energy_layout`), and the loss adds its per-item terms in item
// order. So the results are bit-identical for any number of threads, and to the single loop they replace.
//
// Functions bound by bvh.cpp's module: deform_vertices, farthest_point_sampling. The registration
// loop's per-step entry points are torch operators (torch.ops.torchmeshmetric_registration.*), registered below.
#include <torch/extension.h>
#include <torch/library.h>
#include <ATen/Parallel.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "parallel.h"
#include "triangle.h"

namespace {

using tmm::chunked_for;

// Chunk sizes of the phases, ~10-20 us of work each: a step is ~0.5 ms, so a few dozen chunks balance two threads.
constexpr int64_t CHUNK_VERTS = 256;  // skinning (K rotations per vertex)
constexpr int64_t CHUNK_TERMS = 128;  // closest point on a triangle and robust kernel
constexpr int64_t CHUNK_GATHER = 512;  // per-vertex gradient gather
constexpr int64_t CHUNK_NODES = 16;  // per-node gradient gather and exponential map Jacobian

// Geman-McClure rho(x) = s2 x / (s2 + x) and its derivative s2^2 / (s2 + x)^2 on a squared residual x.
template <typename T>
inline T gm(T x, T s2, T& d) {
  const T den = s2 + x;
  d = (s2 * s2) / (den * den);
  return s2 * x / den;
}

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

  Skinning(const T* R_, const torch::Tensor& tt, const torch::Tensor& gt_, const torch::Tensor& rest_t,
           const torch::Tensor& vidx_t, const torch::Tensor& vw_t)
      : R(R_), t(tt.data_ptr<T>()), g(gt_.data_ptr<T>()), rest(rest_t.data_ptr<T>()),
        vidx(vidx_t.data_ptr<int64_t>()), vw(vw_t.data_ptr<T>()), I(rest_t.size(0)), K(vidx_t.size(1)) {}

  // Deformed position of vertex i into x[0..2].
  void deform(int64_t i, T* x) const { deform_one(R, t, g, rest + 3 * i, vidx + i * K, vw + i * K, K, x); }
};

// (N, 3, 3) rotations of axis-angle vectors (N, 3): kornia's axis_angle_to_rotation_matrix, the same operations in
// the same order (Rodrigues for theta^2 > 1e-6, its second-order series below), with torch's own cos and sin
// kernels, so the matrices are kornia's bit for bit (tested).
template <typename T>
torch::Tensor rotation_matrices(const torch::Tensor& axis_t) {
  const int64_t N = axis_t.size(0);
  const T* v = axis_t.data_ptr<T>();
  std::vector<T> th2(N);
  torch::Tensor safe_t = torch::empty({N}, axis_t.options());
  T* safe = safe_t.data_ptr<T>();
  for (int64_t j = 0; j < N; ++j) {
    const T* a = v + 3 * j;
    th2[j] = (a[0] * a[0] + a[1] * a[1]) + a[2] * a[2];
    safe[j] = th2[j] > T(1e-6) ? th2[j] : T(1);  // kornia's stand-in 1 on the series' rows
  }
  // torch's sqrt is not std::sqrt (not always correctly rounded, measured): its kernels, as kornia.
  const torch::Tensor theta_t = at::sqrt(safe_t), cos_t = at::cos(theta_t), sin_t = at::sin(theta_t);
  const T* theta = theta_t.data_ptr<T>();
  const T* cs = cos_t.data_ptr<T>();
  const T* sn = sin_t.data_ptr<T>();
  torch::Tensor out = torch::empty({N, 3, 3}, axis_t.options());
  T* R = out.data_ptr<T>();
  for (int64_t j = 0; j < N; ++j) {
    const T* a = v + 3 * j;
    T* m = R + 9 * j;
    if (th2[j] > T(1e-6)) {
      const T wx = a[0] / theta[j], wy = a[1] / theta[j], wz = a[2] / theta[j];
      const T c = cs[j], s = sn[j], omc = T(1) - c;
      const T wxwy = wx * wy, wxwz = wx * wz, wywz = wy * wz;
      m[0] = c + wx * wx * omc;
      m[1] = wxwy * omc - wz * s;
      m[2] = wy * s + wxwz * omc;
      m[3] = wz * s + wxwy * omc;
      m[4] = c + wy * wy * omc;
      m[5] = -wx * s + wywz * omc;
      m[6] = -wy * s + wxwz * omc;
      m[7] = wx * s + wywz * omc;
      m[8] = c + wz * wz * omc;
    } else {
      const T ca = T(1) - th2[j] / T(6), cb = T(0.5) - th2[j] / T(24);
      const T rx = a[0], ry = a[1], rz = a[2];
      const T rx2 = rx * rx, ry2 = ry * ry, rz2 = rz * rz, rxry = rx * ry, rxrz = rx * rz, ryrz = ry * rz;
      m[0] = T(1) - cb * (ry2 + rz2);
      m[1] = -ca * rz + cb * rxry;
      m[2] = ca * ry + cb * rxrz;
      m[3] = ca * rz + cb * rxry;
      m[4] = T(1) - cb * (rx2 + rz2);
      m[5] = -ca * rx + cb * ryrz;
      m[6] = -ca * ry + cb * rxrz;
      m[7] = ca * rx + cb * ryrz;
      m[8] = T(1) - cb * (rx2 + ry2);
    }
  }
  return out;
}

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

// Compressed rows: ptr (rows + 1) and the items of each row, listed in increasing code order (a stable counting sort
// of (row, code) pairs produced in increasing code order).
struct Rows {
  torch::Tensor ptr, items;
};

template <typename Emit>
Rows build_rows(int64_t rows, int64_t total, const Emit& emit) {
  Rows out{torch::zeros({rows + 1}, torch::kInt64), torch::empty({total}, torch::kInt64)};
  int64_t* ptr = out.ptr.data_ptr<int64_t>();
  int64_t* items = out.items.data_ptr<int64_t>();
  emit([&](int64_t row, int64_t) { ++ptr[row + 1]; });
  for (int64_t r = 0; r < rows; ++r) ptr[r + 1] += ptr[r];
  std::vector<int64_t> fill(ptr, ptr + rows);
  emit([&](int64_t row, int64_t code) { items[fill[row]++] = code; });
  return out;
}

// The fixed part of the energy between correspondence refreshes, in the order of the serial loop:
// - per touched vertex i, its gradient contributions: data point k (code k), then target sample k through corner c
//   of its face (code S + 3 k + c), in increasing code order;
// - per node j, its gradient contributions: vertex i through skinning slot s (code i K + s), then edge e as its
//   first (code I K + 2 e) or second (code I K + 2 e + 1) node, in increasing code order;
// - the order in which a step visits the data points and target samples (codes k and S + k, by the row of their
//   vertex, their face's first corner) and the nodes (by the first row among their vertices): with the vertices in
//   row order, each thread then reads mostly what it wrote itself (see chunked_for);
// - the sums of the data weights, the reverse weights and the squared edge lengths [wsum, rsum, den].
template <typename T>
std::vector<torch::Tensor> layout_impl(const torch::Tensor& data_idx_t, const torch::Tensor& data_w_t,
                                       const torch::Tensor& rev_faces_t, const torch::Tensor& rev_w_t,
                                       const torch::Tensor& vidx_t, const torch::Tensor& g_t,
                                       const torch::Tensor& edges_t) {
  const int64_t I = vidx_t.size(0), K = vidx_t.size(1), N = g_t.size(0), S = data_idx_t.size(0),
                Q = rev_faces_t.size(0), E = edges_t.size(0);
  const int64_t* di = data_idx_t.data_ptr<int64_t>();
  const int64_t* rf = rev_faces_t.data_ptr<int64_t>();
  const int64_t* vidx = vidx_t.data_ptr<int64_t>();
  const int64_t* ed = edges_t.data_ptr<int64_t>();
  for (int64_t k = 0; k < S; ++k) TORCH_CHECK(di[k] >= 0 && di[k] < I, "energy_layout: data index out of range");
  for (int64_t k = 0; k < 3 * Q; ++k) TORCH_CHECK(rf[k] >= 0 && rf[k] < I, "energy_layout: face corner out of range");
  for (int64_t k = 0; k < I * K; ++k) TORCH_CHECK(vidx[k] >= 0 && vidx[k] < N, "energy_layout: node out of range");
  for (int64_t k = 0; k < 2 * E; ++k) TORCH_CHECK(ed[k] >= 0 && ed[k] < N, "energy_layout: edge node out of range");
  const Rows verts = build_rows(I, S + 3 * Q, [&](const auto& put) {
    for (int64_t k = 0; k < S; ++k) put(di[k], k);
    for (int64_t k = 0; k < 3 * Q; ++k) put(rf[k], S + k);
  });
  const Rows nodes = build_rows(N, I * K + 2 * E, [&](const auto& put) {
    for (int64_t k = 0; k < I * K; ++k) put(vidx[k], k);
    for (int64_t k = 0; k < 2 * E; ++k) put(ed[k], I * K + k);
  });
  const Rows items_by_row = build_rows(I, S + Q, [&](const auto& put) {
    for (int64_t k = 0; k < S; ++k) put(di[k], k);
    for (int64_t k = 0; k < Q; ++k) put(rf[3 * k], S + k);
  });
  const int64_t* nptr = nodes.ptr.data_ptr<int64_t>();
  const int64_t* nitems = nodes.items.data_ptr<int64_t>();
  const Rows nodes_by_row = build_rows(I + 1, N, [&](const auto& put) {
    for (int64_t j = 0; j < N; ++j) {
      const bool has_vertex = nptr[j] < nptr[j + 1] && nitems[nptr[j]] < I * K;
      put(has_vertex ? nitems[nptr[j]] / K : I, j);
    }
  });
  const T* dw = data_w_t.data_ptr<T>();
  const T* rw = rev_w_t.data_ptr<T>();
  const T* g = g_t.data_ptr<T>();
  T wsum = 0, rsum = 0, den = 0;
  for (int64_t k = 0; k < S; ++k) wsum += dw[k];
  for (int64_t k = 0; k < Q; ++k) rsum += rw[k];
  for (int64_t e = 0; e < E; ++e) {
    const int64_t j = ed[2 * e], k = ed[2 * e + 1];
    for (int c = 0; c < 3; ++c) {
      const T dg = g[3 * k + c] - g[3 * j + c];
      den += dg * dg;
    }
  }
  torch::Tensor sums = torch::empty({3}, g_t.options());
  T* sp = sums.data_ptr<T>();
  sp[0] = wsum;
  sp[1] = rsum;
  sp[2] = den;
  return {verts.ptr, verts.items, nodes.ptr, nodes.items, items_by_row.items, nodes_by_row.items, sums};
}

// One refresh's terms laid out for the energy: the touched source vertices (data points and the corners of the faces
// matched by target samples), sorted and distinct, with their rest positions and skinning; the data points' rows
// among them; the corners' rows; then energy_layout's seven tensors.
template <typename T>
std::vector<torch::Tensor> terms_impl(const torch::Tensor& surf_t, const torch::Tensor& rev_face_t,
                                      const torch::Tensor& faces_t, const torch::Tensor& verts_t,
                                      const torch::Tensor& vert_nodes_t, const torch::Tensor& vert_weights_t,
                                      const torch::Tensor& data_w_t, const torch::Tensor& rev_w_t,
                                      const torch::Tensor& nodes_t, const torch::Tensor& edges_t) {
  const int64_t V = verts_t.size(0), K = vert_nodes_t.size(1), S = surf_t.size(0), Q = rev_face_t.size(0),
                F = faces_t.size(0);
  TORCH_CHECK(data_w_t.size(0) == S && rev_w_t.size(0) == Q,
              "energy_terms: one weight per data point and per target sample expected");
  const int64_t* surf = surf_t.data_ptr<int64_t>();
  const int64_t* rfi = rev_face_t.data_ptr<int64_t>();
  const int64_t* faces = faces_t.data_ptr<int64_t>();
  // Every index read below is checked where it is used (the faces themselves only where matched).
  for (int64_t k = 0; k < S; ++k) TORCH_CHECK(surf[k] >= 0 && surf[k] < V, "energy_terms: data index out of range");
  for (int64_t k = 0; k < Q; ++k) {
    TORCH_CHECK(rfi[k] >= 0 && rfi[k] < F, "energy_terms: face index out of range");
    for (int c = 0; c < 3; ++c)
      TORCH_CHECK(faces[3 * rfi[k] + c] >= 0 && faces[3 * rfi[k] + c] < V, "energy_terms: corner out of range");
  }
  // Rows of the touched vertices: marked, then numbered in vertex order (unique's sorted order).
  std::vector<int64_t> row(V, -1);
  for (int64_t k = 0; k < S; ++k) row[surf[k]] = 0;
  for (int64_t k = 0; k < Q; ++k)
    for (int c = 0; c < 3; ++c) row[faces[3 * rfi[k] + c]] = 0;
  int64_t I = 0;
  for (int64_t v = 0; v < V; ++v)
    if (row[v] == 0) row[v] = I++;
  const auto i64 = torch::dtype(torch::kInt64);
  torch::Tensor need = torch::empty({I}, i64), rest = torch::empty({I, 3}, verts_t.options()),
                vidx = torch::empty({I, K}, i64), vw = torch::empty({I, K}, verts_t.options());
  int64_t* nd = need.data_ptr<int64_t>();
  for (int64_t v = 0; v < V; ++v)
    if (row[v] >= 0) nd[row[v]] = v;
  const T* verts = verts_t.data_ptr<T>();
  const int64_t* vn = vert_nodes_t.data_ptr<int64_t>();
  const T* vwt = vert_weights_t.data_ptr<T>();
  T* rp = rest.data_ptr<T>();
  int64_t* ip = vidx.data_ptr<int64_t>();
  T* wp = vw.data_ptr<T>();
  for (int64_t i = 0; i < I; ++i) {
    std::copy(verts + 3 * nd[i], verts + 3 * nd[i] + 3, rp + 3 * i);
    std::copy(vn + K * nd[i], vn + K * nd[i] + K, ip + K * i);
    std::copy(vwt + K * nd[i], vwt + K * nd[i] + K, wp + K * i);
  }
  torch::Tensor data_idx = torch::empty({S}, i64), rev_loc = torch::empty({Q, 3}, i64);
  int64_t* di = data_idx.data_ptr<int64_t>();
  for (int64_t k = 0; k < S; ++k) di[k] = row[surf[k]];
  int64_t* rl = rev_loc.data_ptr<int64_t>();
  for (int64_t k = 0; k < Q; ++k)
    for (int c = 0; c < 3; ++c) rl[3 * k + c] = row[faces[3 * rfi[k] + c]];
  std::vector<torch::Tensor> out{need, rest, vidx, vw, data_idx, rev_loc};
  for (auto& t : layout_impl<T>(data_idx, data_w_t, rev_loc, rev_w_t, vidx, nodes_t, edges_t)) out.push_back(t);
  return out;
}

// The energy's inputs: the graph (axis-angle rotations, their matrices, translations, node positions), the touched
// vertices (rest positions, skinning), the data terms, the reverse terms, the edges, and their layout.
template <typename T>
struct EnergyInputs {
  const T *axis, *R, *t, *g, *rest, *vw, *dpt, *dn, *dw, *smp, *rw, *rb, *rn, *sums;
  const int64_t *vidx, *di, *rf, *ed, *vptr, *vitems, *nptr, *nitems, *item_order, *node_order;
  int64_t N, I, K, S, Q, E;
};

// Loss and gradients [loss, dL/d(axis-angle) (N, 3), dL/dt (N, 3), max |gradient| (double)].
template <typename T>
std::vector<torch::Tensor> energy_core(const EnergyInputs<T>& in, const std::vector<double>& s,
                                       const torch::TensorOptions& opts) {
  const T sigma = T(s[0]), plane_w = T(s[1]), point_w = T(s[2]), rev_w = T(s[3]), data_scale = T(s[4]),
          reg_w = T(s[5]);
  const T s2 = sigma * sigma;
  const int64_t N = in.N, I = in.I, K = in.K, S = in.S, Q = in.Q, E = in.E;
  const T *R = in.R, *t = in.t, *g = in.g, *rest = in.rest, *vw = in.vw;
  const bool reverse_on = rev_w != 0 && Q > 0, reg_on = E > 0 && reg_w != 0;
  const int64_t ER = reg_on ? E : 0;
  // 1. Deformed positions of the touched vertices.
  std::vector<T> x(3 * I);
  chunked_for(I, CHUNK_VERTS, [&](int64_t b, int64_t e_) {
    for (int64_t i = b; i < e_; ++i) deform_one(R, t, g, rest + 3 * i, in.vidx + i * K, vw + i * K, K, &x[3 * i]);
  });
  // 2. Per data point and per target sample: its loss term and its gradient to the deformed positions.
  const T dnorm = data_scale / std::max(in.sums[0], T(1));
  const T rnorm = rev_w * data_scale / std::max(in.sums[1], T(1));
  std::vector<T> term(S + Q, T(0)), grad_data(3 * S), bary(3 * Q), grad_rev(3 * Q);
  chunked_for(S + Q, CHUNK_TERMS, [&](int64_t b, int64_t e_) {
    for (int64_t o = b; o < e_; ++o) {
      const int64_t it = in.item_order[o];
      if (it < S) {
        const int64_t k = it;
        if (in.dw[k] == 0) continue;
        const T* p = &x[3 * in.di[k]];
        const T* q = in.dpt + 3 * k;  // the fixed target point, and the plane through it
        const T dq[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
        const T sq = (dq[0] * dq[0] + dq[1] * dq[1]) + dq[2] * dq[2];
        T d1;
        T e = point_w * gm(sq, s2, d1);
        T gp[3];
        for (int c = 0; c < 3; ++c) gp[c] = point_w * d1 * T(2) * dq[c];
        if (plane_w != 0) {
          const T* n = in.dn + 3 * k;
          const T dist = (dq[0] * n[0] + dq[1] * n[1]) + dq[2] * n[2];
          T d2;
          e += plane_w * gm(dist * dist, s2, d2);
          for (int c = 0; c < 3; ++c) gp[c] += plane_w * d2 * T(2) * dist * n[c];
        }
        const T f = in.dw[k] * dnorm;
        term[k] = f * e;
        for (int c = 0; c < 3; ++c) grad_data[3 * k + c] = f * gp[c];
      } else {
        const int64_t k = it - S;
        if (!reverse_on || in.rw[k] == 0) continue;
        const T* p = in.smp + 3 * k;
        const int64_t* fc = in.rf + 3 * k;
        // The fixed barycentric point of the deformed face: tied faces at the refresh (a sample closest to an
        // edge or a vertex) give the same point, so the energy does not depend on which one the search returned.
        const T* b = in.rb + 3 * k;
        T q[3];
        for (int c = 0; c < 3; ++c) {
          bary[3 * k + c] = b[c];
          q[c] = (b[0] * x[3 * fc[0] + c] + b[1] * x[3 * fc[1] + c]) + b[2] * x[3 * fc[2] + c];
        }
        // Point-to-point + point-to-plane, as the data term, with the source's interpolated normal at the refresh:
        // the plane lets the source slide along the sample's tangent plane between refreshes.
        const T d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
        const T sq = (d[0] * d[0] + d[1] * d[1]) + d[2] * d[2];
        T d1;
        T e = point_w * gm(sq, s2, d1);
        T gq[3];
        for (int c = 0; c < 3; ++c) gq[c] = point_w * d1 * T(2) * d[c];
        if (plane_w != 0) {
          const T* n = in.rn + 3 * k;
          const T dist = (d[0] * n[0] + d[1] * n[1]) + d[2] * n[2];
          T d2;
          e += plane_w * gm(dist * dist, s2, d2);
          for (int c = 0; c < 3; ++c) gq[c] += plane_w * d2 * T(2) * dist * n[c];
        }
        const T f = in.rw[k] * rnorm;
        term[S + k] = f * e;
        for (int c = 0; c < 3; ++c) grad_rev[3 * k + c] = -f * gq[c];  // d/dq, q = sum b_i x_i
      }
    }
  });
  // 3. Per touched vertex: the gradient to its deformed position, its contributions in the serial loop's order.
  std::vector<T> gx(3 * I);
  chunked_for(I, CHUNK_GATHER, [&](int64_t b, int64_t e_) {
    for (int64_t i = b; i < e_; ++i) {
      T acc[3] = {0, 0, 0};
      for (int64_t m = in.vptr[i]; m < in.vptr[i + 1]; ++m) {
        const int64_t code = in.vitems[m];
        if (code < S) {
          if (in.dw[code] == 0) continue;
          for (int c = 0; c < 3; ++c) acc[c] += grad_data[3 * code + c];
        } else {
          const int64_t k = (code - S) / 3, corner = (code - S) % 3;
          if (!reverse_on || in.rw[k] == 0) continue;
          for (int c = 0; c < 3; ++c) acc[c] += bary[3 * k + corner] * grad_rev[3 * k + c];
        }
      }
      for (int c = 0; c < 3; ++c) gx[3 * i + c] = acc[c];
    }
  });
  // The loss: data terms, reverse terms, regulariser, each summed in item order.
  T loss = 0;
  for (int64_t k = 0; k < S; ++k)
    if (in.dw[k] != 0) loss += term[k];
  if (reverse_on)
    for (int64_t k = 0; k < Q; ++k)
      if (in.rw[k] != 0) loss += term[S + k];
  T scale = 0;
  if (reg_on) {
    const T den = std::max(in.sums[2] / T(E), std::numeric_limits<T>::min());
    scale = reg_w / (T(E) * den);
  }
  // 4. Per node: the gradient to its rotation matrix and translation (dx/dR_j = w (v - g_j)^T, dx/dt_j = w; then
  //    its edges, whose residuals R_j (g_k - g_j) + g_j + t_j - (g_k + t_k) each endpoint computes itself), then back
  //    through the exponential map to its axis-angle vector.
  torch::Tensor gV_t = torch::empty({N, 3}, opts), gT_t = torch::empty({N, 3}, opts);
  T* gV = gV_t.data_ptr<T>();
  T* gT = gT_t.data_ptr<T>();
  const int64_t IK = I * K;
  std::vector<T> res_sq(reg_on ? E : 0);
  chunked_for(N, CHUNK_NODES, [&](int64_t b, int64_t e_) {
    for (int64_t o = b; o < e_; ++o) {
      const int64_t j = in.node_order[o];
      T gR[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0}, gt[3] = {0, 0, 0};
      for (int64_t m = in.nptr[j]; m < in.nptr[j + 1]; ++m) {
        const int64_t code = in.nitems[m];
        if (code < IK) {
          const int64_t i = code / K;
          const T* gi = &gx[3 * i];
          if (gi[0] == 0 && gi[1] == 0 && gi[2] == 0) continue;
          const T* v = rest + 3 * i;
          const T w = vw[code];
          const T d[3] = {v[0] - g[3 * j], v[1] - g[3 * j + 1], v[2] - g[3 * j + 2]};
          for (int a = 0; a < 3; ++a) {
            const T wg = w * gi[a];
            gt[a] += wg;
            for (int c = 0; c < 3; ++c) gR[3 * a + c] += wg * d[c];
          }
        } else if (reg_on) {
          const int64_t e = (code - IK) / 2, first = in.ed[2 * e], second = in.ed[2 * e + 1];
          const T dg[3] = {g[3 * second] - g[3 * first], g[3 * second + 1] - g[3 * first + 1],
                           g[3 * second + 2] - g[3 * first + 2]};
          const T* Rj = R + 9 * first;
          T r[3];
          for (int a = 0; a < 3; ++a)
            r[a] = Rj[3 * a] * dg[0] + Rj[3 * a + 1] * dg[1] + Rj[3 * a + 2] * dg[2] + g[3 * first + a] +
                   t[3 * first + a] - (g[3 * second + a] + t[3 * second + a]);
          if ((code - IK) % 2 == 0) {
            res_sq[e] = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
            for (int a = 0; a < 3; ++a) {
              const T gr = T(2) * scale * r[a];
              gt[a] += gr;
              for (int c = 0; c < 3; ++c) gR[3 * a + c] += gr * dg[c];
            }
          } else {
            for (int a = 0; a < 3; ++a) gt[a] -= T(2) * scale * r[a];
          }
        }
      }
      for (int a = 0; a < 3; ++a) gT[3 * j + a] = gt[a];
      rotation_vjp(in.axis + 3 * j, R + 9 * j, gR, gV + 3 * j);
    }
  });
  if (reg_on) {
    T reg = 0;
    for (int64_t e = 0; e < E; ++e) reg += res_sq[e];
    loss += scale * reg;
  }
  double gmax = 0;  // NaN wins, as torch's max
  for (int64_t m = 0; m < 3 * N; ++m) {
    const double a = std::abs(double(gV[m])), b = std::abs(double(gT[m]));
    if (std::isnan(a) || std::isnan(b)) {
      gmax = std::numeric_limits<double>::quiet_NaN();
      break;
    }
    gmax = std::max(gmax, std::max(a, b));
  }
  return {torch::full({}, loss, opts), gV_t, gT_t, torch::full({}, gmax, torch::dtype(torch::kFloat64))};
}

template <typename T>
EnergyInputs<T> energy_inputs(const torch::Tensor& axis, const T* R, const torch::Tensor& t, const torch::Tensor& g,
                              const torch::Tensor& rest, const torch::Tensor& vidx, const torch::Tensor& vw,
                              const torch::Tensor& data_idx, const torch::Tensor& data_pt,
                              const torch::Tensor& data_n, const torch::Tensor& data_w, const torch::Tensor& samples,
                              const torch::Tensor& rev_faces, const torch::Tensor& rev_w,
                              const torch::Tensor& rev_bary, const torch::Tensor& rev_n,
                              const torch::Tensor& edges, const std::vector<torch::Tensor>& layout) {
  TORCH_CHECK(layout.size() == 7, "deformation energy: 7 layout tensors expected");
  EnergyInputs<T> in;
  in.axis = axis.data_ptr<T>();
  in.R = R;
  in.t = t.data_ptr<T>();
  in.g = g.data_ptr<T>();
  in.rest = rest.data_ptr<T>();
  in.vw = vw.data_ptr<T>();
  in.dpt = data_pt.data_ptr<T>();
  in.dn = data_n.data_ptr<T>();
  in.dw = data_w.data_ptr<T>();
  in.smp = samples.data_ptr<T>();
  in.rw = rev_w.data_ptr<T>();
  in.rb = rev_bary.data_ptr<T>();
  in.rn = rev_n.data_ptr<T>();
  in.sums = layout[6].data_ptr<T>();
  in.vidx = vidx.data_ptr<int64_t>();
  in.di = data_idx.data_ptr<int64_t>();
  in.rf = rev_faces.data_ptr<int64_t>();
  in.ed = edges.data_ptr<int64_t>();
  in.vptr = layout[0].data_ptr<int64_t>();
  in.vitems = layout[1].data_ptr<int64_t>();
  in.nptr = layout[2].data_ptr<int64_t>();
  in.nitems = layout[3].data_ptr<int64_t>();
  in.item_order = layout[4].data_ptr<int64_t>();
  in.node_order = layout[5].data_ptr<int64_t>();
  in.N = g.size(0);
  in.I = rest.size(0);
  in.K = vidx.size(1);
  in.S = data_idx.size(0);
  in.Q = samples.size(0);
  in.E = edges.size(0);
  TORCH_CHECK(data_pt.numel() == 3 * in.S && data_n.numel() == 3 * in.S && rev_bary.numel() == 3 * in.Q &&
                  rev_n.numel() == 3 * in.Q,
              "deformation energy: one point and normal per data point and per target sample expected");
  TORCH_CHECK(layout[0].numel() == in.I + 1 && layout[2].numel() == in.N + 1 &&
                  layout[4].numel() == in.S + in.Q && layout[5].numel() == in.N,
              "deformation energy: the layout belongs to other terms");
  return in;
}

void check_cpu(std::initializer_list<const torch::Tensor*> xs, const char* who) {
  for (const auto* x : xs) TORCH_CHECK(x->is_contiguous() && x->device().is_cpu(), who, ": contiguous CPU tensors expected");
}

bool is_double(const torch::Tensor& x, const char* who) {
  if (x.scalar_type() == torch::kFloat64) return true;
  TORCH_CHECK(x.scalar_type() == torch::kFloat32, who, ": float32 or float64 expected");
  return false;
}

// Farthest-point sampling from `start` until every point is within sqrt(s2) of a chosen one: the choices of the loop
// of deformation_graph._fps, bit for bit. dmin[i] is the running minimum std::min(dmin[i], sq(i, c)) over the chosen
// centres c, sq the squared distance with the loop's operations (dx*dx + dy*dy) + dz*dz (dx = p_i - c, no fused
// multiply-add: -ffp-contract=off); each choice is the first maximum of dmin (the first NaN, if any, as torch's
// argmax), and the sampling stops when double(dmin[far]) <= s2.
//
// The same values from less work: the points sit in the leaves of a k-d tree (median splits of the longest side, at
// most FPS_LEAF points a leaf, each leaf in index order), each node holding the box of its points' coordinates and
// the maximum of its points' dmin with the lowest index attaining it. A new centre c leaves a node alone when
// L >= dmax, L the lower bound below computed from the box. That skip changes no bit: it needs sq(i, c) >= dmin[i]
// (then std::min keeps dmin[i]) for every point i of the node, and L is no margin-padded estimate but a bound on the
// *computed* sq. Per axis, g = lo - c where c < lo, g = hi - c where c > hi, else 0, with the operation sq does
// (p_i - c, rounded in T); L = (gx*gx + gy*gy) + gz*gz in T in sq's order. Rounding is monotone (x <= y gives
// fl(x) <= fl(y), whatever the rounding mode, subnormals flushed or not), so lo <= p_i (c < lo) gives
// fl(p_i - c) >= fl(lo - c) >= 0, hi >= p_i (c > hi) gives fl(p_i - c) <= fl(hi - c) <= 0, and in both cases
// |dx| >= |g|, so fl(dx*dx) >= fl(g*g) (and fl(dx*dx) >= 0 = fl(g*g) where c is inside); each addition of
// nonnegative terms is monotone too, so sq(i, c) >= L >= dmax >= dmin[i]. A NaN coordinate makes sq(i, c) NaN,
// which std::min never takes: the box ignores NaN coordinates, and a NaN bound or a NaN dmax (nothing compares
// true) never skips. The maximum is then the root's: the nodes merge their children's (value, index) with the
// loop's order (NaN first, then the larger value, then the lower index), and a leaf scans its points in index order
// as the loop does. One thread: the registration calls it between its own parallel phases.
constexpr int64_t FPS_LEAF = 128;

template <typename T>
struct FpsNode {
  T lo[3], hi[3];  // the box of the node's coordinates (NaN ones left out; lo > hi on an axis with none)
  T dmax;  // the largest dmin of the node's points in the loop's order (NaN if any is NaN)
  int64_t arg;  // the lowest point index attaining dmax
  int64_t begin, end;  // the node's points: tree-order slots [begin, end)
  int32_t left, right;  // children, -1 for a leaf
};

// (a, ia) comes before (b, ib) in the order the loop's argmax takes: NaN first, then the larger value, then the
// lower index.
template <typename T>
inline bool fps_before(T a, int64_t ia, T b, int64_t ib) {
  const bool na = std::isnan(a), nb = std::isnan(b);
  if (na != nb) return na;
  if (!na && a != b) return a > b;
  return ia < ib;
}

template <typename T>
class FpsTree {
 public:
  FpsTree(const T* p, int64_t n) : p_(p), idx_(n), x_(n), y_(n), z_(n), d_(n) {
    std::vector<Pt> pts(n);
    T lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::numeric_limits<T>::infinity();
      hi[a] = -std::numeric_limits<T>::infinity();
    }
    for (int64_t i = 0; i < n; ++i) {
      pts[i] = {{p[3 * i], p[3 * i + 1], p[3 * i + 2]}, i};
      for (int a = 0; a < 3; ++a) {
        lo[a] = pts[i].c[a] < lo[a] ? pts[i].c[a] : lo[a];
        hi[a] = pts[i].c[a] > hi[a] ? pts[i].c[a] : hi[a];
      }
    }
    nodes_.reserve(static_cast<size_t>(4 * (n / FPS_LEAF + 1)));
    build(pts, 0, n, lo, hi);
    for (int64_t k = 0; k < n; ++k) {
      idx_[k] = pts[k].i;
      x_[k] = pts[k].c[0];
      y_[k] = pts[k].c[1];
      z_[k] = pts[k].c[2];
    }
  }

  // dmin = sq(., c) for the first centre.
  void reset(int64_t c) {
    set_centre(c);
    reset_node(0);
  }

  // dmin = min(dmin, sq(., c)) for a new centre.
  void add(int64_t c) {
    set_centre(c);
    add_node(0);
  }

  // The first maximum of dmin: its value and index.
  T dmax() const { return nodes_[0].dmax; }
  int64_t arg() const { return nodes_[0].arg; }

 private:
  struct Pt {
    T c[3];
    int64_t i;
  };

  // The node of the points pts[begin, end) inside the cell [clo, chi] (the bounds of the splits above, which choose
  // the axis: the cell's longest side); its box, the tight one, is made from its points (a leaf) or its children's.
  int32_t build(std::vector<Pt>& pts, int64_t begin, int64_t end, const T* clo, const T* chi) {
    const int32_t id = static_cast<int32_t>(nodes_.size());
    nodes_.emplace_back();
    FpsNode<T> nd;
    nd.begin = begin;
    nd.end = end;
    nd.left = nd.right = -1;
    if (end - begin <= FPS_LEAF) {
      // Index order: a leaf's scan meets ties as the loop does.
      std::sort(pts.begin() + begin, pts.begin() + end, [](const Pt& a, const Pt& b) { return a.i < b.i; });
      for (int a = 0; a < 3; ++a) {
        nd.lo[a] = std::numeric_limits<T>::infinity();
        nd.hi[a] = -std::numeric_limits<T>::infinity();
      }
      for (int64_t k = begin; k < end; ++k)
        for (int a = 0; a < 3; ++a) {
          const T v = pts[k].c[a];
          if (v < nd.lo[a]) nd.lo[a] = v;  // a NaN compares false: left out
          if (v > nd.hi[a]) nd.hi[a] = v;
        }
    } else {
      int axis = 0;
      for (int a = 1; a < 3; ++a)
        if (chi[a] - clo[a] > chi[axis] - clo[axis]) axis = a;
      const int64_t mid = begin + (end - begin) / 2;
      // A strict weak order with NaN after every number (std::less is none with NaN).
      std::nth_element(pts.begin() + begin, pts.begin() + mid, pts.begin() + end, [axis](const Pt& p, const Pt& q) {
        const T a = p.c[axis], b = q.c[axis];
        return a < b || (std::isnan(b) && !std::isnan(a));
      });
      T lhi[3] = {chi[0], chi[1], chi[2]}, rlo[3] = {clo[0], clo[1], clo[2]};
      lhi[axis] = rlo[axis] = pts[mid].c[axis];
      nd.left = build(pts, begin, mid, clo, lhi);
      nd.right = build(pts, mid, end, rlo, chi);
      const FpsNode<T>& l = nodes_[nd.left];
      const FpsNode<T>& r = nodes_[nd.right];
      for (int a = 0; a < 3; ++a) {
        nd.lo[a] = r.lo[a] < l.lo[a] ? r.lo[a] : l.lo[a];
        nd.hi[a] = r.hi[a] > l.hi[a] ? r.hi[a] : l.hi[a];
      }
    }
    nodes_[id] = nd;
    return id;
  }

  void set_centre(int64_t c) {
    cx_ = p_[3 * c];
    cy_ = p_[3 * c + 1];
    cz_ = p_[3 * c + 2];
  }

  // The leaf's maximum in the loop's order: its points are in index order, so the loop's own scan.
  void scan(FpsNode<T>& nd) const {
    int64_t far = nd.begin;
    for (int64_t k = nd.begin + 1; k < nd.end; ++k)
      if (d_[k] > d_[far] || (std::isnan(d_[k]) && !std::isnan(d_[far]))) far = k;
    nd.dmax = d_[far];
    nd.arg = idx_[far];
  }

  void merge(FpsNode<T>& nd) const {
    const FpsNode<T>& l = nodes_[nd.left];
    const FpsNode<T>& r = nodes_[nd.right];
    const bool right = fps_before(r.dmax, r.arg, l.dmax, l.arg);
    nd.dmax = right ? r.dmax : l.dmax;
    nd.arg = right ? r.arg : l.arg;
  }

  // sq(i, c) with the loop's operations, i a tree-order slot.
  T sq(int64_t k) const {
    const T dx = x_[k] - cx_, dy = y_[k] - cy_, dz = z_[k] - cz_;
    T s = dx * dx;
    s += dy * dy;
    s += dz * dz;
    return s;
  }

  void reset_node(int32_t id) {
    FpsNode<T>& nd = nodes_[id];
    if (nd.left < 0) {
      for (int64_t k = nd.begin; k < nd.end; ++k) d_[k] = sq(k);
      scan(nd);
    } else {
      reset_node(nd.left);
      reset_node(nd.right);
      merge(nd);
    }
  }

  // The box's bound on sq(i, c) for every point i of the node (see above): the gap per axis as sq rounds p_i - c.
  static T gap(T c, T lo, T hi) { return c < lo ? lo - c : (c > hi ? hi - c : T(0)); }

  void add_node(int32_t id) {
    FpsNode<T>& nd = nodes_[id];
    const T gx = gap(cx_, nd.lo[0], nd.hi[0]), gy = gap(cy_, nd.lo[1], nd.hi[1]), gz = gap(cz_, nd.lo[2], nd.hi[2]);
    T bound = gx * gx;
    bound += gy * gy;
    bound += gz * gz;
    if (bound >= nd.dmax) return;  // no dmin of the node changes (false on a NaN: visited)
    if (nd.left < 0) {
      for (int64_t k = nd.begin; k < nd.end; ++k) d_[k] = std::min(d_[k], sq(k));
      scan(nd);
    } else {
      add_node(nd.left);
      add_node(nd.right);
      merge(nd);
    }
  }

  const T* p_;
  std::vector<int64_t> idx_;  // the point index of each tree-order slot
  std::vector<T> x_, y_, z_, d_;  // coordinates and dmin in tree order
  std::vector<FpsNode<T>> nodes_;  // nodes_[0] is the root
  T cx_ = 0, cy_ = 0, cz_ = 0;  // the current centre
};

template <typename T>
std::vector<int64_t> fps_impl(const T* p, int64_t n, int64_t start, double s2) {
  std::vector<int64_t> chosen{start};
  FpsTree<T> tree(p, n);
  tree.reset(start);
  for (;;) {
    if (static_cast<double>(tree.dmax()) <= s2) break;  // compared in double, as float(dmin[far]) <= s2
    const int64_t far = tree.arg();
    chosen.push_back(far);
    tree.add(far);
  }
  return chosen;
}

// Face cross product (b - a) x (c - a) and its norm with the operations of Mesh._face_cross and the row norm: torch's
// CPU kernels (AVX2 / AVX-512 builds) contract a*b - c*d into fma(a, b, -(c*d)) and accumulate the squares by fma.
template <typename T>
inline void face_cross(const T* verts, const int64_t* f, T* n) {
  const T *a = verts + 3 * f[0], *b = verts + 3 * f[1], *c = verts + 3 * f[2];
  const T u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const T v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  n[0] = std::fma(u[1], v[2], -(u[2] * v[1]));
  n[1] = std::fma(u[2], v[0], -(u[0] * v[2]));
  n[2] = std::fma(u[0], v[1], -(u[1] * v[0]));
}

// x / |x| with structures._unit's convention: exactly zero where the norm is zero.
template <typename T>
inline void unit(const T* x, T* out) {
  const T norm = std::sqrt(std::fma(x[2], x[2], std::fma(x[1], x[1], x[0] * x[0])));
  for (int c = 0; c < 3; ++c) out[c] = norm > 0 ? x[c] / norm : T(0);
}

// Every vertex deformed by the graph (rotations from axis-angle), and the area-weighted unit vertex normals of the
// deformed mesh at the vertices `at` (Mesh.vertex_normals: face cross products summed per vertex in (corner, face)
// order, the order of its three index_add passes; `inc_ptr` / `inc_items` from incident_faces). std::fma and
// std::sqrt round once: the same bits on every CPU, and torch's on its AVX2 / AVX-512 kernels (not its scalar ones).
template <typename T>
std::vector<torch::Tensor> deform_normals_impl(const torch::Tensor& axis, const torch::Tensor& t,
                                               const torch::Tensor& g, const torch::Tensor& rest,
                                               const torch::Tensor& vidx, const torch::Tensor& vw,
                                               const torch::Tensor& faces, const torch::Tensor& inc_ptr,
                                               const torch::Tensor& inc_items, const torch::Tensor& at_t) {
  const torch::Tensor R = rotation_matrices<T>(axis);
  const Skinning<T> skin(R.data_ptr<T>(), t, g, rest, vidx, vw);
  torch::Tensor out = torch::empty({skin.I, 3}, rest.options());
  T* x = out.data_ptr<T>();
  chunked_for(skin.I, 4 * CHUNK_VERTS, [&](int64_t s, int64_t e) {
    for (int64_t i = s; i < e; ++i) skin.deform(i, x + 3 * i);
  });
  const int64_t A = at_t.size(0), F = faces.size(0);
  const int64_t* at = at_t.data_ptr<int64_t>();
  const int64_t* fc = faces.data_ptr<int64_t>();
  const int64_t* ptr = inc_ptr.data_ptr<int64_t>();
  const int64_t* items = inc_items.data_ptr<int64_t>();
  TORCH_CHECK(inc_ptr.numel() == skin.I + 1, "deform_normals: incident faces of another mesh");
  for (int64_t a = 0; a < A; ++a) TORCH_CHECK(at[a] >= 0 && at[a] < skin.I, "deform_normals: vertex out of range");
  torch::Tensor normals = torch::empty({A, 3}, rest.options());
  T* nv = normals.data_ptr<T>();
  chunked_for(A, CHUNK_GATHER, [&](int64_t s, int64_t e) {
    for (int64_t a = s; a < e; ++a) {
      T acc[3] = {0, 0, 0};
      for (int64_t m = ptr[at[a]]; m < ptr[at[a] + 1]; ++m) {
        T n[3];
        face_cross(x, fc + 3 * (items[m] % F), n);
        for (int c = 0; c < 3; ++c) acc[c] += n[c];
      }
      unit(acc, nv + 3 * a);
    }
  });
  return {out, normals};
}

// ---- torch operators (torch.ops.torchmeshmetric_registration) ----

std::vector<torch::Tensor> energy_layout(const torch::Tensor& data_idx, const torch::Tensor& data_w,
                                         const torch::Tensor& rev_faces, const torch::Tensor& rev_w,
                                         const torch::Tensor& vert_nodes, const torch::Tensor& nodes,
                                         const torch::Tensor& edges) {
  check_cpu({&data_idx, &data_w, &rev_faces, &rev_w, &vert_nodes, &nodes, &edges}, "energy_layout");
  if (is_double(nodes, "energy_layout"))
    return layout_impl<double>(data_idx, data_w, rev_faces, rev_w, vert_nodes, nodes, edges);
  return layout_impl<float>(data_idx, data_w, rev_faces, rev_w, vert_nodes, nodes, edges);
}

std::vector<torch::Tensor> energy_terms(const torch::Tensor& surf, const torch::Tensor& rev_face_idx,
                                        const torch::Tensor& faces, const torch::Tensor& verts,
                                        const torch::Tensor& vert_nodes, const torch::Tensor& vert_weights,
                                        const torch::Tensor& data_w, const torch::Tensor& rev_w,
                                        const torch::Tensor& nodes, const torch::Tensor& edges) {
  check_cpu({&surf, &rev_face_idx, &faces, &verts, &vert_nodes, &vert_weights, &data_w, &rev_w, &nodes, &edges},
            "energy_terms");
  if (is_double(verts, "energy_terms"))
    return terms_impl<double>(surf, rev_face_idx, faces, verts, vert_nodes, vert_weights, data_w, rev_w, nodes, edges);
  return terms_impl<float>(surf, rev_face_idx, faces, verts, vert_nodes, vert_weights, data_w, rev_w, nodes, edges);
}

template <typename T>
std::vector<torch::Tensor> energy_step_impl(const torch::Tensor& axis, const torch::Tensor& t, const torch::Tensor& g,
                                            const torch::Tensor& rest, const torch::Tensor& vidx,
                                            const torch::Tensor& vw, const torch::Tensor& data_idx,
                                            const torch::Tensor& data_pt, const torch::Tensor& data_n,
                                            const torch::Tensor& data_w, const torch::Tensor& samples,
                                            const torch::Tensor& rev_faces, const torch::Tensor& rev_w,
                                            const torch::Tensor& rev_bary, const torch::Tensor& rev_n,
                                            const torch::Tensor& edges, const std::vector<torch::Tensor>& layout,
                                            const std::vector<double>& scalars) {
  const torch::Tensor R = rotation_matrices<T>(axis);
  const auto in = energy_inputs<T>(axis, R.data_ptr<T>(), t, g, rest, vidx, vw, data_idx, data_pt, data_n, data_w,
                                   samples, rev_faces, rev_w, rev_bary, rev_n, edges, layout);
  return energy_core<T>(in, scalars, t.options());
}

// [loss, dL/d(axis-angle), dL/dt, max |gradient|] at the graph's current parameters.
std::vector<torch::Tensor> energy_step(const torch::Tensor& axis, const torch::Tensor& t, const torch::Tensor& g,
                                       const torch::Tensor& rest, const torch::Tensor& vidx, const torch::Tensor& vw,
                                       const torch::Tensor& data_idx, const torch::Tensor& data_pt,
                                       const torch::Tensor& data_n, const torch::Tensor& data_w,
                                       const torch::Tensor& samples, const torch::Tensor& rev_faces,
                                       const torch::Tensor& rev_w, const torch::Tensor& rev_bary,
                                       const torch::Tensor& rev_n, const torch::Tensor& edges,
                                       at::TensorList layout_list, at::ArrayRef<double> scalars_ref) {
  check_cpu({&axis, &t, &g, &rest, &vidx, &vw, &data_idx, &data_pt, &data_n, &data_w, &samples, &rev_faces, &rev_w,
             &rev_bary, &rev_n, &edges}, "energy_step");
  const std::vector<torch::Tensor> layout(layout_list.begin(), layout_list.end());
  const std::vector<double> scalars(scalars_ref.begin(), scalars_ref.end());
  TORCH_CHECK(scalars.size() == 6, "energy_step: 6 scalars expected");
  if (is_double(axis, "energy_step"))
    return energy_step_impl<double>(axis, t, g, rest, vidx, vw, data_idx, data_pt, data_n, data_w, samples, rev_faces,
                                    rev_w, rev_bary, rev_n, edges, layout, scalars);
  return energy_step_impl<float>(axis, t, g, rest, vidx, vw, data_idx, data_pt, data_n, data_w, samples, rev_faces,
                                 rev_w, rev_bary, rev_n, edges, layout, scalars);
}

// Per vertex, its faces as codes c F + f (corner c of face f) in increasing order: [ptr (V + 1), items (3 F)].
std::vector<torch::Tensor> incident_faces(const torch::Tensor& faces, int64_t num_verts) {
  check_cpu({&faces}, "incident_faces");
  TORCH_CHECK(faces.scalar_type() == torch::kInt64 && faces.dim() == 2 && faces.size(1) == 3,
              "incident_faces: (F, 3) int64 faces expected");
  const int64_t F = faces.size(0);
  const int64_t* f = faces.data_ptr<int64_t>();
  for (int64_t k = 0; k < 3 * F; ++k)
    TORCH_CHECK(f[k] >= 0 && f[k] < num_verts, "incident_faces: vertex index out of range");
  const Rows rows = build_rows(num_verts, 3 * F, [&](const auto& put) {
    for (int c = 0; c < 3; ++c)
      for (int64_t k = 0; k < F; ++k) put(f[3 * k + c], c * F + k);
  });
  return {rows.ptr, rows.items};
}

std::vector<torch::Tensor> deform_normals(const torch::Tensor& axis, const torch::Tensor& t, const torch::Tensor& g,
                                          const torch::Tensor& rest, const torch::Tensor& vidx,
                                          const torch::Tensor& vw, const torch::Tensor& faces,
                                          const torch::Tensor& inc_ptr, const torch::Tensor& inc_items,
                                          const torch::Tensor& at) {
  check_cpu({&axis, &t, &g, &rest, &vidx, &vw, &faces, &inc_ptr, &inc_items, &at}, "deform_normals");
  if (is_double(axis, "deform_normals"))
    return deform_normals_impl<double>(axis, t, g, rest, vidx, vw, faces, inc_ptr, inc_items, at);
  return deform_normals_impl<float>(axis, t, g, rest, vidx, vw, faces, inc_ptr, inc_items, at);
}

torch::Tensor axis_angle_rotations(const torch::Tensor& axis) {
  check_cpu({&axis}, "axis_angle_rotations");
  return is_double(axis, "axis_angle_rotations") ? rotation_matrices<double>(axis) : rotation_matrices<float>(axis);
}

}  // namespace

TORCH_LIBRARY(torchmeshmetric_registration, m) {
  m.def("energy_layout(Tensor data_idx, Tensor data_w, Tensor rev_faces, Tensor rev_w, Tensor vert_nodes, "
        "Tensor nodes, Tensor edges) -> Tensor[]", &energy_layout);
  m.def("energy_terms(Tensor surf, Tensor rev_face_idx, Tensor faces, Tensor verts, Tensor vert_nodes, "
        "Tensor vert_weights, Tensor data_w, Tensor rev_w, Tensor nodes, Tensor edges) -> Tensor[]", &energy_terms);
  m.def("energy_step(Tensor axis, Tensor t, Tensor g, Tensor rest, Tensor vidx, Tensor vw, Tensor data_idx, "
        "Tensor data_pt, Tensor data_n, Tensor data_w, Tensor samples, Tensor rev_faces, Tensor rev_w, "
        "Tensor rev_bary, Tensor rev_n, Tensor edges, Tensor[] layout, float[] scalars) -> Tensor[]", &energy_step);
  m.def("incident_faces(Tensor faces, int num_verts) -> Tensor[]", &incident_faces);
  m.def("deform_normals(Tensor axis, Tensor t, Tensor g, Tensor rest, Tensor vidx, Tensor vw, Tensor faces, "
        "Tensor inc_ptr, Tensor inc_items, Tensor at) -> Tensor[]", &deform_normals);
  m.def("axis_angle_rotations(Tensor axis) -> Tensor", &axis_angle_rotations);
}

// ---- functions bound by bvh.cpp's module ----

torch::Tensor farthest_point_sampling(torch::Tensor points, int64_t start, double spacing2) {
  TORCH_CHECK(points.is_contiguous() && points.device().is_cpu(), "farthest_point_sampling: contiguous CPU points");
  TORCH_CHECK(points.dim() == 2 && points.size(1) == 3 && points.size(0) > 0,
              "farthest_point_sampling: (N, 3) points with N >= 1 expected");
  TORCH_CHECK(start >= 0 && start < points.size(0), "farthest_point_sampling: start out of range");
  std::vector<int64_t> out;
  if (is_double(points, "farthest_point_sampling"))
    out = fps_impl<double>(points.data_ptr<double>(), points.size(0), start, spacing2);
  else
    out = fps_impl<float>(points.data_ptr<float>(), points.size(0), start, spacing2);
  auto t = torch::empty({static_cast<int64_t>(out.size())}, torch::dtype(torch::kInt64));
  std::copy(out.begin(), out.end(), t.data_ptr<int64_t>());
  return t;
}

torch::Tensor deform_vertices(torch::Tensor R, torch::Tensor t, torch::Tensor g, torch::Tensor rest,
                              torch::Tensor vidx, torch::Tensor vw) {
  check_cpu({&R, &t, &g, &rest, &vidx, &vw}, "deform_vertices");
  torch::Tensor out = torch::empty({rest.size(0), 3}, rest.options());
  AT_DISPATCH_FLOATING_TYPES(R.scalar_type(), "deform_vertices", [&] {
    const Skinning<scalar_t> skin(R.data_ptr<scalar_t>(), t, g, rest, vidx, vw);
    scalar_t* x = out.data_ptr<scalar_t>();
    chunked_for(skin.I, 4 * CHUNK_VERTS, [&](int64_t s, int64_t e) {
      for (int64_t i = s; i < e; ++i) skin.deform(i, x + 3 * i);
    });
  });
  return out;
}
