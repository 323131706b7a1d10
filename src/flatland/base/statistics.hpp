// Two-sided quantiles of the normal and Student's t distributions, computed with the basic
// operations and portable_math only, so an error bar is the same bits on every platform.
#pragma once

namespace flatland {

// P(|Z| <= z) for a standard normal Z (z >= 0): erf(z / sqrt 2) by its series of positive terms,
// erf(x) = 2/sqrt(pi) e^(-x^2) sum_n 2^n x^(2n+1) / (1 3 5 ... (2n+1)).
double normal_two_sided(double z);
// P(|T| <= t) for Student's t with an odd number of degrees of freedom nu = 2m - 1 (t >= 0): the
// density is proportional to (1 + x^2)^-m in x = t / sqrt(nu), whose integral from 0 to X follows
// J_1 = atan X, J_m = X / (2 (m-1) (1+X^2)^(m-1)) + (2m-3) / (2 (m-1)) J_(m-1), and J_m(infinity)
// likewise from pi/2.
double student_t_two_sided(double t, int odd_dof);
// The z with normal_two_sided(z) = probability, and the t with student_t_two_sided(t, dof) =
// probability (probability in (0, 1)), by bisection to the last bit.
double normal_quantile_two_sided(double probability);
double student_t_quantile_two_sided(double probability, int odd_dof);

namespace portable {
// atan by argument reduction (1/x beyond 1, the pi/6 rotation beyond tan(pi/12)) and its Taylor
// series, within a few ulps.
double atan(double x);
}  // namespace portable

}  // namespace flatland
