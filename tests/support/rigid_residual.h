#pragma once
// Largest difference between two spatial-error fields after removing the best rigid-body
// motion of the workpiece frame (translation and small rotation: the gauge no line
// measurement fixes) and, with `free_squareness`, the three shears of the squareness errors.

#include <Eigen/Dense>
#include <vector>

namespace mtcal::testing {

/// `points_mm`: ideal points; `diffs_um`: the difference of the fields there.
inline double residualAfterRigidMotionUm(const std::vector<Eigen::Vector3d>& points_mm,
                                         const std::vector<Eigen::Vector3d>& diffs_um, bool free_squareness = false) {
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(3 * static_cast<Eigen::Index>(points_mm.size()), free_squareness ? 9 : 6);
  Eigen::VectorXd b(a.rows());
  for (std::size_t i = 0; i < points_mm.size(); ++i) {
    const auto r = 3 * static_cast<Eigen::Index>(i);
    const Eigen::Vector3d& p = points_mm[i];
    a.block<3, 3>(r, 0).setIdentity();
    Eigen::Matrix3d skew;  // w x p = -[p]x w
    skew << 0, p.z(), -p.y(), -p.z(), 0, p.x(), p.y(), -p.x(), 0;
    a.block<3, 3>(r, 3) = skew;
    if (free_squareness) {  // x with y (EC0Y), x with z (EB0Z), y with z (EA0Z)
      a(r, 6) = p.y();
      a(r, 7) = p.z();
      a(r + 1, 8) = p.z();
    }
    b.segment<3>(r) = diffs_um[i];
  }
  return (a * a.colPivHouseholderQr().solve(b) - b).cwiseAbs().maxCoeff();
}

}  // namespace mtcal::testing
