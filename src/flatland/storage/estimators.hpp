// From deposited power to the coefficients of the received power per unit length on a curve's
// storage: the Galerkin projection, the local quasi-interpolant, and the clamp that keeps a
// density nonnegative.
#pragma once

#include <cstddef>

#include "flatland/scene/scene.hpp"
#include "flatland/storage/curve_storage.hpp"

namespace flatland {

// Estimators turn deposited powers p_k (sum over photons of power x phi_k(hit), so that
// E[p_k] = integral(phi_k R ds) for the received power per unit length R) into coefficients b_k of
// R = sum_k b_k phi_k. `stride` is the distance between consecutive coefficients of one channel
// (the channel count of an interleaved layout). docs/method.md compares them.
//
// The Galerkin (L2) estimate: the spline whose moments against every phi_k equal the deposits,
// M b = p. It reproduces every function of the spline space, so its bias is O(h^(p+1)) up to the
// curve's ends and its discontinuity nodes, and sum_k b_k integral(phi_k ds) = sum_k p_k exactly
// (the functions sum to one). It can dip below zero next to sharp features and by noise; it is not
// clamped (see clamp_keeping_power).
void galerkin_estimate(const CurveStorage& storage, const double* deposits, double* coefficients, std::size_t stride);

// The local quasi-interpolant (dual functionals, docs/method.md): b_k = sum_j w_kj p_j over the 2w + 1
// deposits nearest to k (w = degree + 1; Hermite: 3) inside k's region between discontinuity
// nodes (C0 and C-1 nodes, the curve's ends), with the weights of least variance, for photons of
// locally uniform density, among those that are exact when R is a polynomial of degree q on the
// region: min w^T G w subject to V^T w = c, G the local Gram matrix, V_jm = integral(phi_j x^m ds)
// and c_m the target functional of x^m. With `nodal_values` false the target is the B-spline
// coefficient (the blossom of x^m at the function's interior knots, q = degree): the
// reconstruction's bias is O(h^(q+1)) everywhere, at the cost of a banded sparse product. With
// `nodal_values` true (hat functions only: Hermite storage) the target is R at the hat's peak with
// q = 3, the nodal values a cubic Hermite interpolant wants. A function that straddles a C0 node
// is estimated from each side and the two combined by inverse variance; one-sided windows near
// ends and nodes keep the window's size where the region allows, and a region too short for q + 1
// functions lowers q there.
void build_local_estimator(const Scene& scene, const Curve& curve, CurveStorage& storage, bool nodal_values);
void local_estimate(const CurveStorage& storage, const double* deposits, double* coefficients, std::size_t stride);

// Negative coefficients set to zero and the rest scaled so that sum_k b_k integral(phi_k ds) equals
// `power`: a nonnegative density holding a given power (the photon origins' sampling density).
// False, with every coefficient zero, when nothing positive is left to scale.
bool clamp_keeping_power(const CurveStorage& storage, double* coefficients, std::size_t stride, double power);

}  // namespace flatland
