// Point-triangle closest point and squared distance, shared by the BVH (bvh.cpp) and the registration energy
// (deformation_energy.cpp). The operations mirror point_triangle._region_candidates / closest_point_on_triangle
// in their order and dtype; compile with -ffp-contract=off (no FMA contraction) to keep them bit-identical.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

namespace tmm {

template <typename T>
inline T dot3(const T* x, const T* y) {
  return x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
}

template <typename T>
inline T safe_div(T num, T den) {
  return den > 0 ? num / den : T(0);
}

template <typename T>
inline T clamp01(T x) {
  return std::min(std::max(x, T(0)), T(1));
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

// point_triangle._region_candidates for one point and one face: the clamped edge parameters, the face
// barycentrics v, w, and the squared distances [edge AB, edge AC, edge BC, face] (face: +inf outside).
template <typename T>
struct RegionCandidates {
  T t_ab, t_ac, t_bc, v, w;
  T sq[4];
};

template <typename T>
inline RegionCandidates<T> region_candidates(const FaceData<T>& f, const T* p) {
  RegionCandidates<T> r;
  T ap[3], bp[3];
  for (int k = 0; k < 3; ++k) {
    ap[k] = p[k] - f.a[k];
    bp[k] = p[k] - f.b[k];
  }
  r.t_ab = clamp01(safe_div(dot3(ap, f.ab), dot3(f.ab, f.ab)));
  r.t_ac = clamp01(safe_div(dot3(ap, f.ac), dot3(f.ac, f.ac)));
  r.t_bc = clamp01(safe_div(dot3(bp, f.bc), dot3(f.bc, f.bc)));
  T d_ab[3], d_ac[3], d_bc[3];
  for (int k = 0; k < 3; ++k) {
    d_ab[k] = ap[k] - r.t_ab * f.ab[k];
    d_ac[k] = ap[k] - r.t_ac * f.ac[k];
    d_bc[k] = bp[k] - r.t_bc * f.bc[k];
  }
  r.sq[0] = dot3(d_ab, d_ab);
  r.sq[1] = dot3(d_ac, d_ac);
  r.sq[2] = dot3(d_bc, d_bc);
  r.sq[3] = std::numeric_limits<T>::infinity();
  r.v = r.w = T(0);  // safe_div's value for a zero-area face (nn = 0), whose face candidate is never inside
  if (f.nn > 0) {
    // cross(ap, ac) . n and cross(ab, ap) . n
    const T c1[3] = {ap[1] * f.ac[2] - ap[2] * f.ac[1], ap[2] * f.ac[0] - ap[0] * f.ac[2],
                     ap[0] * f.ac[1] - ap[1] * f.ac[0]};
    const T c2[3] = {f.ab[1] * ap[2] - f.ab[2] * ap[1], f.ab[2] * ap[0] - f.ab[0] * ap[2],
                     f.ab[0] * ap[1] - f.ab[1] * ap[0]};
    r.v = dot3(c1, f.n) / f.nn;
    r.w = dot3(c2, f.n) / f.nn;
    if (r.v >= 0 && r.w >= 0 && r.v + r.w <= 1) {
      T d_f[3];
      for (int k = 0; k < 3; ++k) d_f[k] = (ap[k] - r.v * f.ab[k]) - r.w * f.ac[k];
      r.sq[3] = dot3(d_f, d_f);
    }
  }
  return r;
}

// Squared distance from p to a triangle, mirroring point_triangle._region_candidates(...)[-1].amin(-1).
template <typename T>
inline T tri_sq_dist(const FaceData<T>& f, const T* p) {
  const RegionCandidates<T> r = region_candidates(f, p);
  return std::min(std::min(std::min(r.sq[0], r.sq[1]), r.sq[2]), r.sq[3]);
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
