#pragma once
// Minimal absolute pose from three bearing-point pairs: Lambda Twist
// (Persson & Nordberg, ECCV 2018), written from the paper's mathematics.
//
// Problem: unit bearings y_i in the camera, points X_i in the world; find
// cam_from_world = (R, t) and depths lambda_i > 0 with lambda_i y_i = R X_i + t.
// Rigidity gives, for each pair (i, j), with c_ij = y_i . y_j and
// a_ij = |X_i - X_j|^2,
//   lambda_i^2 + lambda_j^2 - 2 c_ij lambda_i lambda_j = a_ij,
// i.e. lambda^T M_ij lambda = a_ij with M_ij the 3x3 symmetric matrix of that
// quadratic form. Eliminating the right-hand sides gives two homogeneous
// conics in lambda,
//   D1 = a23 M12 - a12 M23,   D2 = a23 M13 - a13 M23,
// and every solution lies on every conic of their pencil D1 + g D2. For a root
// g of the cubic det(D1 + g D2) = 0,
//   det(A + g B) = det A + g tr(adj(A) B) + g^2 tr(A adj(B)) + g^3 det B,
// the conic D0 = D1 + g D2 is degenerate: with eigenvalues s_a < 0 < s_c (and
// ~0) and eigenvectors e_a, e_c, lambda^T D0 lambda = 0 splits into the two
// planes (e_c -+ sqrt(-s_a / s_c) e_a) . lambda = 0. On each plane lambda =
// alpha u + beta w (u, w an orthonormal basis of the plane); D2 gives a
// homogeneous quadratic in (alpha, beta), hence two directions, and the sum of
// the three rigidity equations (a positive definite form) gives the scale.
// Up to four solutions; each lambda is polished by Gauss-Newton on the three
// equations before the pose is read off:
//   R [X1-X2, X1-X3, (X1-X2)x(X1-X3)] = [P1-P2, P1-P3, (P1-P2)x(P1-P3)],
//   P_i = lambda_i y_i,   t = P1 - R X1.

#include "config/frames.h"

#include <Eigen/Core>

#include <array>
#include <vector>

namespace lifmcr::registration {

// Appends the cam_from_world poses consistent with the three pairs (0 to 4)
// to *cam_from_world and returns how many. Bearings need not be normalised
// but must be non-zero; a degenerate sample (collinear points, coincident
// bearings) yields none. Does not allocate when *cam_from_world has room for four.
int SolveP3P(const std::array<Eigen::Vector3d, 3>& bearings,
             const std::array<Eigen::Vector3d, 3>& points_in_world,
             std::vector<Pose>* cam_from_world);

// Real roots of x^3 + b x^2 + c x + d = 0 in *roots (1 or 3 of them, ascending,
// polished by Newton's method); returns how many.
int SolveMonicCubic(double b, double c, double d, double roots[3]);

}  // namespace lifmcr::registration
