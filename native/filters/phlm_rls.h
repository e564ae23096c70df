// SPDX-License-Identifier: Apache-2.0
// The per-pixel recursive-least-squares model of PHLM (seed 002 §4, eqs. 2-7;
// METHODS.md "PHLM"), in a numerically stabilised form, templated on the
// scalar type (float = the product, double = the test oracle).
//
// The model of one pixel: x = [1, z] (d = 4, z the RGB temporal feature),
// coefficients beta (4x3: row 0 the intercept, rows 1-3 the slopes of z) and
// the inverse covariance P (4x4). The paper updates P directly (eq. 7):
//   Q = P x / (lambda + x'P x),  beta += Q e',  P = (P - Q x'P) / lambda.
// That form is not stable in float32 (METHODS.md): P grows as lambda^-k in
// directions x never excites, round-off breaks its symmetry and positive
// definiteness. We keep the SAME estimator with three changes:
//  1. Factorised P = U D U' (U unit upper triangular, D > 0) updated by
//     Bierman's rank-1 algorithm (Bierman 1977, "Factorization Methods for
//     Discrete Sequential Estimation", the UD measurement update): P is
//     symmetric by construction and positive definite as long as D > 0, which
//     the update keeps (each new d_j = d_j * alpha_{j-1} / alpha_j with
//     alpha_j > 0), and it carries about twice the precision of the plain
//     form in the small eigenvalues.
//  2. Exponential forgetting as a separate step D /= lambda before the update;
//     with measurement variance 1 this is exactly eqs. 6-7:
//     P/lambda - (P/lambda)x x'(P/lambda)/(1 + x'(P/lambda)x) = (P - Q x'P)/lambda.
//  3. Regularised forgetting against wind-up: each frame one coordinate axis
//     e_k (k = frame mod 4, the same for every pixel) receives a pseudo-
//     measurement of information w_k = 4 (1 - lambda) / P0_kk that leaves
//     beta unchanged (zero innovation), P0 = diag(p0, ps, ps, ps) the reset
//     covariance. In information form R = P^-1 this adds w_k e_k e_k' per
//     frame; with R = P0^-1 at a reset, R >= lambda^3 P0^-1 at every later
//     frame (each axis is refreshed every 4 frames with w_k / (1 - lambda^4)
//     >= 1 / P0_kk), so  P <= P0 / lambda^3  and
//     trace P <= (p0 + 3 ps) / lambda^3  (the bound the tests assert): P never
//     grows past ~its reset value in any direction. Where x excites the model
//     the data add |x|^2 >= 1 per frame against ~(1 - lambda)/P0_kk from the
//     regulariser: there the estimator is the paper's; it differs only where
//     the paper's P would wind up past its initial value.
// A weighted sample (jitter weighting) is a measurement of variance 1/w.
//
// The update functions below are written once for T = a scalar (float,
// double) or a GCC vector of scalars (phlm.cpp updates 8 pixels at once, lane
// i = pixel i, the record "transposed": m[j] holds scalar j of every lane).
// Only lane-wise IEEE operations in the same order, so a lane gives the bits
// of the scalar form (the build has no FMA contraction).
#pragma once

#include <cmath>

// Vector lane types pass only between always-inlined functions: the ABI note
// of -Wpsabi says nothing here.
#pragma GCC diagnostic ignored "-Wpsabi"

// Always inlined: into both copies of phlm's row loop (temporal/isa.h).
#define CRISP_PHLM_INLINE __attribute__((always_inline)) inline

namespace crisp::phlm {

constexpr int kDims = 4;          // x = [1, zR, zG, zB]
constexpr int kBeta = 0;          // 12 coefficients, row-major: beta[j][c] at kBeta + 3 j + c
constexpr int kU = 12;            // 6 off-diagonals of U, U(i,j) (i < j) at kU + j (j - 1) / 2 + i
constexpr int kD = 18;            // 4 diagonal entries of D
constexpr int kZ = 22;            // the temporal feature z (RGB), stored with the model
constexpr int kRecord = 25;       // scalars per pixel

inline constexpr int uIndex(int i, int j) { return kU + j * (j - 1) / 2 + i; }

// 0 and 1 as T (broadcast to every lane for a vector T).
template <class T>
CRISP_PHLM_INLINE T zeroOf() {
  return T{};
}
template <class T>
CRISP_PHLM_INLINE T oneOf() {
  return T{} + 1;
}

// Reset (seed 002 §6 "Initialization"): intercept = colour, slopes 0,
// P = diag(p0, ps, ps, ps) (the paper: p0 = ps = 1000; see phlm.cpp).
template <class T>
CRISP_PHLM_INLINE void resetModel(T* m, const T colour[3], const T& p0, const T& ps) {
  for (int c = 0; c < 3; ++c) m[kBeta + c] = colour[c];
  for (int i = 3; i < 12; ++i) m[kBeta + i] = zeroOf<T>();
  for (int i = 0; i < 6; ++i) m[kU + i] = zeroOf<T>();
  m[kD] = p0;
  for (int i = 1; i < 4; ++i) m[kD + i] = ps;
}

// f = beta' x (eq. 4).
template <class T>
CRISP_PHLM_INLINE void predict(const T* m, const T x[kDims], T f[3]) {
  for (int c = 0; c < 3; ++c) {
    T s = m[kBeta + c] * x[0];
    for (int j = 1; j < kDims; ++j) s += m[kBeta + 3 * j + c] * x[j];
    f[c] = s;
  }
}

// Bierman's UD measurement update for the measurement h (entries h[0..first-1]
// must be 0 and are not read) with variance r (inverseR = 1/r, given so the
// caller can hoist it): P <- P - P h h'P / (r + h'P h). gain[] (may be null)
// receives K = P h / (r + h'P h) (the old P). Returns 1 / (r + h'P h).
// One division per row: the reciprocal of alpha_j serves row j and j + 1.
// `first` is a template argument so that the loops unroll with constant
// indices and the record stays in registers (a run-time first kept it in
// memory, and its store-to-load chain was the hottest line of phlm's pan).
template <int first, class T>
CRISP_PHLM_INLINE T biermanUpdate(T* m, const T h[kDims], const T& r, const T& inverseR, T* gain) {
  T f[kDims], v[kDims], b[kDims];
  for (int j = first; j < kDims; ++j) {
    T s = h[j];
    for (int i = first; i < j; ++i) s += m[uIndex(i, j)] * h[i];  // f = U' h
    f[j] = s;
    v[j] = m[kD + j] * s;  // v = D f
  }
  for (int i = 0; i < first; ++i) b[i] = zeroOf<T>();
  T alpha = r, inversePrevious = inverseR;
  for (int j = first; j < kDims; ++j) {
    const T previous = alpha;
    alpha = previous + f[j] * v[j];
    const T inverse = oneOf<T>() / alpha;
    m[kD + j] = m[kD + j] * previous * inverse;
    b[j] = v[j];
    const T p = -f[j] * inversePrevious;
    for (int i = 0; i < j; ++i) {
      const T u = m[uIndex(i, j)];
      m[uIndex(i, j)] = u + b[i] * p;
      b[i] = b[i] + u * v[j];
    }
    inversePrevious = inverse;
  }
  if (gain)
    for (int j = 0; j < kDims; ++j) gain[j] = b[j] * inversePrevious;
  return inversePrevious;
}

// Exponential forgetting (eq. 7's 1/lambda): P <- P / lambda.
template <class T>
CRISP_PHLM_INLINE void forget(T* m, const T& inverseLambda) {
  for (int j = 0; j < kDims; ++j) m[kD + j] *= inverseLambda;
}

// Point 3 above: information w = 1 / variance on axis k, beta unchanged.
template <int axis, class T>
CRISP_PHLM_INLINE void regularise(T* m, const T& variance, const T& inverseVariance) {
  T h[kDims] = {zeroOf<T>(), zeroOf<T>(), zeroOf<T>(), zeroOf<T>()};
  h[axis] = oneOf<T>();
  biermanUpdate<axis>(m, h, variance, inverseVariance, static_cast<T*>(nullptr));
}
// The same on an axis known at run time, 0-3 (the frame's axis, frame mod 4).
template <class T>
CRISP_PHLM_INLINE void regularise(T* m, int axis, const T& variance, const T& inverseVariance) {
  switch (axis) {
    case 0: return regularise<0>(m, variance, inverseVariance);
    case 1: return regularise<1>(m, variance, inverseVariance);
    case 2: return regularise<2>(m, variance, inverseVariance);
    case 3: return regularise<3>(m, variance, inverseVariance);
    default: __builtin_unreachable();
  }
}

// One RLS step (eqs. 5-7) on the error e = y - beta'x of this frame, with
// sample weight w > 0 (measurement variance 1/w). Returns the output gain
// g = x'K = x'P x / (1/w + x'P x) in [0, 1): the updated prediction is
// beta'x + g e, a convex combination of the prediction and y.
template <class T>
CRISP_PHLM_INLINE T rlsUpdate(T* m, const T x[kDims], const T e[3], const T& variance, const T& inverseVariance) {
  T k[kDims];
  const T inverseAlpha = biermanUpdate<0>(m, x, variance, inverseVariance, k);
  for (int j = 0; j < kDims; ++j)
    for (int c = 0; c < 3; ++c) m[kBeta + 3 * j + c] += k[j] * e[c];
  return oneOf<T>() - variance * inverseAlpha;
}

// P = U D U' in double (tests, diagnostics).
template <class T>
inline void covariance(const T* m, double P[kDims][kDims]) {
  double U[kDims][kDims] = {};
  for (int i = 0; i < kDims; ++i) {
    U[i][i] = 1.0;
    for (int j = i + 1; j < kDims; ++j) U[i][j] = double(m[uIndex(i, j)]);
  }
  for (int i = 0; i < kDims; ++i)
    for (int j = 0; j < kDims; ++j) {
      double s = 0.0;
      for (int k = 0; k < kDims; ++k) s += U[i][k] * double(m[kD + k]) * U[j][k];
      P[i][j] = s;
    }
}

}  // namespace crisp::phlm
