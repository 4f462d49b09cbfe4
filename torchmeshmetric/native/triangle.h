// Point-triangle closest point and squared distance, shared by the BVH (bvh.cpp) and the registration energy
// (deformation_energy.cpp). The operations mirror kernels/triangle.py region_candidates / closest_point_on_triangle
// in their order and dtype; compile with -ffp-contract=off (no FMA contraction) to keep them bit-identical.
//
// The distance is written once for a value type S that is either a scalar T or a vector of lanes of T (GCC/Clang
// vector extensions): lane operations are the same IEEE operations as the scalar ones, so the BVH computes the
// distances of several faces side by side with the very same results. Hence branch-free code: selections, not ifs.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <utility>

// Inlined even where the compiler's heuristics decline: the BVH's leaf test calls the distance once per block.
#if defined(__GNUC__)
#define TMM_ALWAYS_INLINE __attribute__((always_inline)) inline
#else
#define TMM_ALWAYS_INLINE inline
#endif

namespace tmm {

// The scalar type of S (S itself, or the element of a lane vector).
template <typename S, bool = std::is_arithmetic_v<S>>
struct Lane {
  using type = S;
};
template <typename S>
struct Lane<S, false> {
  using type = std::decay_t<decltype(std::declval<S>()[0])>;
};
template <typename S>
using lane_t = typename Lane<S>::type;

// x in every lane of S.
template <typename S>
inline S splat(lane_t<S> x) {
  if constexpr (std::is_arithmetic_v<S>) {
    return x;
  } else {
    S v;
    for (int l = 0; l < static_cast<int>(sizeof(S) / sizeof(lane_t<S>)); ++l) v[l] = x;
    return v;
  }
}

// std::min and std::max, lane-wise: (b < a) ? b : a and (a < b) ? b : a.
template <typename S>
inline S vmin(S a, S b) {
  return b < a ? b : a;
}

template <typename S>
inline S vmax(S a, S b) {
  return a < b ? b : a;
}

template <typename T>
inline T dot3(const T* x, const T* y) {
  return x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
}

// num / den where den > 0, else 0 (the division runs on a harmless divisor where den <= 0).
template <typename S>
inline S safe_div(S num, S den) {
  const auto ok = den > splat<S>(0);
  const S q = num / (ok ? den : splat<S>(1));
  return ok ? q : splat<S>(0);
}

template <typename S>
inline S clamp01(S x) {
  return vmin(vmax(x, splat<S>(0)), splat<S>(1));
}

// Per-face data in leaf order: a, b, ab, ac, bc, n = ab x ac, nn = n.n (same operations as the torch kernel).
template <typename T>
struct FaceData {
  T a[3], b[3], ab[3], ac[3], bc[3], n[3];
  T nn;
};

// FaceData of the triangle (a, b, c), with the operations of the torch kernel.
template <typename T>
inline FaceData<T> face_data(const T* a, const T* b, const T* c) {
  FaceData<T> d;
  for (int k = 0; k < 3; ++k) {
    d.a[k] = a[k];
    d.b[k] = b[k];
    d.ab[k] = b[k] - a[k];
    d.ac[k] = c[k] - a[k];
    d.bc[k] = c[k] - b[k];
  }
  d.n[0] = d.ab[1] * d.ac[2] - d.ab[2] * d.ac[1];
  d.n[1] = d.ab[2] * d.ac[0] - d.ab[0] * d.ac[2];
  d.n[2] = d.ab[0] * d.ac[1] - d.ab[1] * d.ac[0];
  d.nn = dot3(d.n, d.n);
  return d;
}

// kernels/triangle.py region_candidates for one point and one face: the clamped edge parameters, the face
// barycentrics v, w, and the squared distances [edge AB, edge AC, edge BC, face] (face: +inf outside).
template <typename S>
struct RegionCandidates {
  S t_ab, t_ac, t_bc, v, w;
  S sq[4];
};

template <typename S>
TMM_ALWAYS_INLINE RegionCandidates<S> region_candidates(const FaceData<S>& f, const S* p) {
  const S zero = splat<S>(0), one = splat<S>(1);
  RegionCandidates<S> r;
  S ap[3], bp[3];
  for (int k = 0; k < 3; ++k) {
    ap[k] = p[k] - f.a[k];
    bp[k] = p[k] - f.b[k];
  }
  r.t_ab = clamp01(safe_div(dot3(ap, f.ab), dot3(f.ab, f.ab)));
  r.t_ac = clamp01(safe_div(dot3(ap, f.ac), dot3(f.ac, f.ac)));
  r.t_bc = clamp01(safe_div(dot3(bp, f.bc), dot3(f.bc, f.bc)));
  S d_ab[3], d_ac[3], d_bc[3];
  for (int k = 0; k < 3; ++k) {
    d_ab[k] = ap[k] - r.t_ab * f.ab[k];
    d_ac[k] = ap[k] - r.t_ac * f.ac[k];
    d_bc[k] = bp[k] - r.t_bc * f.bc[k];
  }
  r.sq[0] = dot3(d_ab, d_ab);
  r.sq[1] = dot3(d_ac, d_ac);
  r.sq[2] = dot3(d_bc, d_bc);
  // Face candidate: v = cross(ap, ac) . n / nn, w = cross(ab, ap) . n / nn, the projection's squared distance when
  // inside, +inf outside. v = w = 0 for a zero-area face (nn = 0, as safe_div), whose candidate is never inside.
  const auto area = f.nn > zero;
  const S nn = area ? f.nn : one;
  const S c1[3] = {ap[1] * f.ac[2] - ap[2] * f.ac[1], ap[2] * f.ac[0] - ap[0] * f.ac[2],
                   ap[0] * f.ac[1] - ap[1] * f.ac[0]};
  const S c2[3] = {f.ab[1] * ap[2] - f.ab[2] * ap[1], f.ab[2] * ap[0] - f.ab[0] * ap[2],
                   f.ab[0] * ap[1] - f.ab[1] * ap[0]};
  const S v = dot3(c1, f.n) / nn;
  const S w = dot3(c2, f.n) / nn;
  r.v = area ? v : zero;
  r.w = area ? w : zero;
  S d_f[3];
  for (int k = 0; k < 3; ++k) d_f[k] = (ap[k] - r.v * f.ab[k]) - r.w * f.ac[k];
  // u = (1 - v) - w >= 0 as the face's barycentric is computed (kernels/triangle.py: not v + w <= 1).
  const auto inside = area & (r.v >= zero) & (r.w >= zero) & ((one - r.v) - r.w >= zero);
  r.sq[3] = inside ? dot3(d_f, d_f) : splat<S>(std::numeric_limits<lane_t<S>>::infinity());
  return r;
}

// Squared distance from p to a triangle, mirroring kernels/triangle.py region_candidates(...)[-1].amin(-1).
template <typename S>
inline S tri_sq_dist(const FaceData<S>& f, const S* p) {
  const RegionCandidates<S> r = region_candidates(f, p);
  return vmin(vmin(vmin(r.sq[0], r.sq[1]), r.sq[2]), r.sq[3]);
}

// Closest point on the triangle (a, b, c) to p, as closest_point_on_triangle: four candidates, the first minimum
// (torch.argmin), barycentrics of that candidate, closest = (b0 a + b1 b) + b2 c. Writes bary and closest, returns
// the squared distance.
template <typename T>
inline T closest_on_face(const T* a, const T* b, const T* c, const T* p, T* bary, T* closest) {
  const RegionCandidates<T> r = region_candidates(face_data(a, b, c), p);
  const T* cand = r.sq;
  int region = 0;  // first minimum, as torch.argmin
  for (int j = 1; j < 4; ++j)
    if (cand[j] < cand[region]) region = j;
  T bw[3];
  switch (region) {
    case 0: bw[0] = T(1) - r.t_ab; bw[1] = r.t_ab; bw[2] = T(0); break;
    case 1: bw[0] = T(1) - r.t_ac; bw[1] = T(0); bw[2] = r.t_ac; break;
    case 2: bw[0] = T(0); bw[1] = T(1) - r.t_bc; bw[2] = r.t_bc; break;
    default: bw[0] = (T(1) - r.v) - r.w; bw[1] = r.v; bw[2] = r.w; break;
  }
  T diff[3];
  for (int k = 0; k < 3; ++k) {
    const T q = (bw[0] * a[k] + bw[1] * b[k]) + bw[2] * c[k];
    closest[k] = q;
    bary[k] = bw[k];
    diff[k] = p[k] - q;
  }
  return dot3(diff, diff);
}

}  // namespace tmm
