#include <cmath>
#include <cstdlib>

#include <gtest/gtest.h>

#include "nirslam/geometry/symmetric_eigenvalues.hpp"

namespace nirslam {
namespace {

// Checked through the characteristic polynomial rather than against Eigen's solver, whose
// instantiation the helper exists to avoid: the values sum to the trace, multiply to the
// determinant, come in ascending order, and m - lambda I is singular for each.
TEST(SymmetricEigenvalues, SolveTheCharacteristicPolynomialInAscendingOrder) {
  std::srand(3);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Matrix2d m = Eigen::Matrix2d::Random() * (trial % 7 == 0 ? 1e-6 : 10.0);
    m(0, 1) = m(1, 0);
    const Eigen::Vector2d values = symmetric_eigenvalues(m);
    const double scale = m.norm();
    EXPECT_LE(values[0], values[1]) << m;
    EXPECT_NEAR(values.sum(), m.trace(), 1e-12 * scale) << m;
    EXPECT_NEAR(values.prod(), m.determinant(), 1e-12 * scale * scale) << m;
    for (int i = 0; i < 2; ++i)
      EXPECT_NEAR((m - values[i] * Eigen::Matrix2d::Identity()).determinant(), 0.0, 1e-12 * scale * scale) << m;
  }
}

TEST(SymmetricEigenvalues, KnownCases) {
  EXPECT_EQ(symmetric_eigenvalues(Eigen::Vector2d(3.0, 1.0).asDiagonal()), Eigen::Vector2d(1.0, 3.0));
  EXPECT_EQ(symmetric_eigenvalues(Eigen::Matrix2d::Identity() * 2.0), Eigen::Vector2d(2.0, 2.0));
  Eigen::Matrix2d line;  // points along one line: one direction without spread
  line << 1.0, 2.0, 2.0, 4.0;
  const Eigen::Vector2d values = symmetric_eigenvalues(line);
  EXPECT_NEAR(values[0], 0.0, 1e-15);
  EXPECT_NEAR(values[1], 5.0, 1e-15);
}

}  // namespace
}  // namespace nirslam
