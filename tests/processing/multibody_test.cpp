#include "mtcal/processing/multibody.h"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

MultibodyModel patentMachine() {
  std::ifstream in(std::string(MTCAL_EXAMPLES_DIR) + "/machines/vmc3-cn104200063.model.json");
  return MultibodyModel::fromJson(nlohmann::json::parse(in), "vmc3-cn104200063.model.json");
}

Eigen::VectorXd randomErrors(const MultibodyModel& m, unsigned seed, double magnitude) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-magnitude, magnitude);
  Eigen::VectorXd e(static_cast<Eigen::Index>(m.terms().size()));
  for (auto& v : e) v = u(rng);
  return e;
}

TEST(Multibody, ThePatentMachineHas21ErrorsAndItsLowerOrderBodyArray) {
  const auto m = patentMachine();
  EXPECT_EQ(m.terms().size(), 21u);
  EXPECT_EQ(m.coordinates(), (std::vector<std::string>{"x", "y", "z"}));
  EXPECT_EQ(m.lowerBody("tool", 0), "tool");  // L^0(j) = j
  EXPECT_EQ(m.lowerBody("tool", 1), "Z");
  EXPECT_EQ(m.lowerBody("tool", 3), "X");
  EXPECT_EQ(m.lowerBody("tool", 4), "bed");
  EXPECT_EQ(m.lowerBody("tool", 9), "bed");  // L^r(0) = 0
  EXPECT_EQ(m.lowerBody("workpiece", 1), "bed");
  const Eigen::Vector3d p = m.idealPoint(Eigen::Vector3d(100.0, 200.0, 300.0));
  EXPECT_TRUE(p.isApprox(Eigen::Vector3d(100.0, 200.0, 180.0), 1e-12));
}

// The analytic Jacobian (generators between prefix and suffix products) against central
// finite differences of the full homogeneous-transform model, at several positions.
TEST(Multibody, JacobianMatchesFiniteDifferencesOfTheFullModel) {
  const auto m = patentMachine();
  const Eigen::Index n = static_cast<Eigen::Index>(m.terms().size());
  for (const Eigen::Vector3d& q :
       {Eigen::Vector3d(50, 50, 50), Eigen::Vector3d(600, 20, 310), Eigen::Vector3d(333, 444, 12)}) {
    const Eigen::Matrix3Xd jac = m.jacobian(q);
    for (Eigen::Index t = 0; t < n; ++t) {
      Eigen::VectorXd h = Eigen::VectorXd::Zero(n);
      h(t) = 1.0;  // 1 um or 1 urad
      const Eigen::Vector3d fd = (m.spatialErrorUm(q, h) - m.spatialErrorUm(q, -h)) / 2.0;
      EXPECT_TRUE(fd.isApprox(jac.col(t), 1e-6) || (fd - jac.col(t)).norm() < 1e-9)
          << m.terms()[static_cast<std::size_t>(t)].name << " at " << q.transpose() << ": fd " << fd.transpose()
          << " vs " << jac.col(t).transpose();
    }
  }
}

// The same check for a point off the tool point (a reflector on the spindle) and for the
// orientation of the tool relative to the workpiece (what angular optics read).
TEST(Multibody, PointAndOrientationJacobiansMatchFiniteDifferences) {
  const auto m = patentMachine();
  const Eigen::Index n = static_cast<Eigen::Index>(m.terms().size());
  const Eigen::Vector3d reflector(15.0, -40.0, 65.0);
  const Eigen::Vector3d q(420, 130, 250);
  const Eigen::Matrix3Xd jac = m.jacobian(q, reflector);
  const Eigen::Matrix3Xd rot = m.orientationJacobian(q);
  for (Eigen::Index t = 0; t < n; ++t) {
    Eigen::VectorXd h = Eigen::VectorXd::Zero(n);
    h(t) = 1.0;
    const Eigen::Vector3d fd = (m.actualPoint(q, -h, reflector) - m.actualPoint(q, h, reflector)) / 2.0 * 1000.0;
    EXPECT_LT((fd - jac.col(t)).norm(), 1e-7) << m.terms()[static_cast<std::size_t>(t)].name;
    const Eigen::Vector3d fd_rot = (m.orientationErrorUrad(q, h) - m.orientationErrorUrad(q, -h)) / 2.0;
    EXPECT_LT((fd_rot - rot.col(t)).norm(), 1e-7) << m.terms()[static_cast<std::size_t>(t)].name;
  }
  // Every rotation of the patent machine's carriages turns the tool by itself, about its
  // own axis, squareness included; translations do not turn it.
  for (const char* name : {"EAX", "EBY", "ECZ", "EC0Y"}) {
    const auto& term = m.terms()[static_cast<std::size_t>(m.termIndex(name))];
    Eigen::Vector3d unit = Eigen::Vector3d::Zero();
    unit(static_cast<int>(term.component) - 3) = 1.0;
    EXPECT_LT((rot.col(m.termIndex(name)) - unit).norm(), 1e-9) << name;
  }
  EXPECT_LT(rot.col(m.termIndex("EXX")).norm(), 1e-12);
}

MultibodyModel exampleMachine(const std::string& file) {
  std::ifstream in(std::string(MTCAL_EXAMPLES_DIR) + "/machines/" + file);
  return MultibodyModel::fromJson(nlohmann::json::parse(in), file);
}

// The shipped configurations of the later issues, with rotary axes (degrees): their
// Jacobians against central differences of the full product at random poses.
TEST(Multibody, GrinderAndGantryConfigurationsHaveConsistentJacobians) {
  const auto grinder = exampleMachine("grinder-xc-mks8332a.model.json");
  EXPECT_EQ(grinder.coordinates(), (std::vector<std::string>{"x", "c"}));
  EXPECT_EQ(grinder.terms().size(), 16u);  // 6 of X, 6 of C, 4 location errors of C
  const auto gantry = exampleMachine("gantry-xyz-ca-cn106017326.model.json");
  EXPECT_EQ(gantry.coordinates(), (std::vector<std::string>{"x", "y", "z", "c", "a"}));
  EXPECT_EQ(gantry.terms().size(), 41u);  // 18 + 3 squareness + 2 x (6 motion + 4 location)
  // Ideal poses: the gantry's tool point hangs 550 mm under the ram at A = C = 0; A = 90 deg
  // swings the 300 mm tool to -Y about the wrist centre (rotation about +X).
  EXPECT_TRUE(gantry.idealPoint((Eigen::VectorXd(5) << 200, 100, 300, 0, 0).finished())
                  .isApprox(Eigen::Vector3d(200, 100, -250), 1e-12));
  EXPECT_TRUE(gantry.idealPoint((Eigen::VectorXd(5) << 200, 100, 300, 0, 90).finished())
                  .isApprox(Eigen::Vector3d(200, 400, 50), 1e-12));
  // The grinder's contact point seen from the camshaft turns with C: at C = 90 deg the
  // wheel at x = 40 mm is at -y in the camshaft's frame.
  EXPECT_TRUE(grinder.idealPoint(Eigen::Vector2d(40, 90)).isApprox(Eigen::Vector3d(0, -40, 0), 1e-12));
  for (const auto* m : {&grinder, &gantry}) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-180.0, 180.0);
    for (int pose = 0; pose < 3; ++pose) {
      Eigen::VectorXd q(static_cast<Eigen::Index>(m->coordinates().size()));
      for (auto& v : q) v = u(rng);
      const Eigen::Matrix3Xd jac = m->jacobian(q);
      const Eigen::Matrix3Xd rot = m->orientationJacobian(q);
      for (Eigen::Index t = 0; t < jac.cols(); ++t) {
        Eigen::VectorXd h = Eigen::VectorXd::Zero(jac.cols());
        h(t) = 1.0;
        const Eigen::Vector3d fd = (m->spatialErrorUm(q, h) - m->spatialErrorUm(q, -h)) / 2.0;
        EXPECT_LT((fd - jac.col(t)).norm(), 1e-7) << m->name() << " " << m->terms()[static_cast<std::size_t>(t)].name;
        const Eigen::Vector3d fd_rot = (m->orientationErrorUrad(q, h) - m->orientationErrorUrad(q, -h)) / 2.0;
        EXPECT_LT((fd_rot - rot.col(t)).norm(), 1e-7)
            << m->name() << " " << m->terms()[static_cast<std::size_t>(t)].name;
      }
    }
  }
}

// Full minus linear is second order: doubling the errors quadruples the difference.
TEST(Multibody, FullMinusLinearIsSecondOrder) {
  const auto m = patentMachine();
  const Eigen::Vector3d q(420.0, 310.0, 150.0);
  const Eigen::VectorXd e = randomErrors(m, 3, 20.0);  // up to 20 um and 20 urad
  auto gap = [&](double s) { return (m.spatialErrorUm(q, s * e) - m.spatialErrorLinearUm(q, s * e)).norm(); };
  const double g1 = gap(1.0), g2 = gap(2.0), g4 = gap(4.0);
  EXPECT_GT(g1, 0.0);
  EXPECT_NEAR(g2 / g1, 4.0, 0.05);
  EXPECT_NEAR(g4 / g2, 4.0, 0.05);
  EXPECT_LT(g1, 1e-3 * m.spatialErrorUm(q, e).norm());  // and small against E itself
}

// Closed form of the equivalent errors for this topology, derived by hand: a serial chain
// bed-X-Y-Z-tool with parallel axes displaces the tool point by sum_k (delta_k + eps_k x r_k),
// r_k the vector from joint k's frame to the tool point: r_X = (0, y, z - L), r_Y = (0, 0, z - L),
// r_Z = (0, 0, -L), L = 120 mm; squareness acts before its axis moves (EC0Y with r_X, EB0Z and
// EA0Z with r_Y). E = P_ideal - P = -(that sum); rotations in urad times mm give nm.
TEST(Multibody, EquivalentErrorsMatchTheClosedFormOfThePatentMachine) {
  const auto m = patentMachine();
  const double length = 120.0;
  for (unsigned seed = 1; seed <= 5; ++seed) {
    const Eigen::VectorXd e = randomErrors(m, seed, 15.0);
    auto v = [&](const char* name) { return e(m.termIndex(name)); };
    std::mt19937 rng(seed + 100);
    std::uniform_real_distribution<double> u(0.0, 600.0);
    const double x = u(rng), y = u(rng), z = u(rng);
    (void)x;  // no lever arm depends on x in this chain
    const Eigen::Vector3d r_x(0.0, y, z - length), r_y(0.0, 0.0, z - length), r_z(0.0, 0.0, -length);
    auto move = [&](const char* dx, const char* dy, const char* dz, const char* rx, const char* ry, const char* rz,
                    const Eigen::Vector3d& r) -> Eigen::Vector3d {  // not auto: an Eigen expression would dangle
      const Eigen::Vector3d eps(v(rx), v(ry), v(rz));
      return Eigen::Vector3d(v(dx), v(dy), v(dz)) + eps.cross(r) * 1e-3;
    };
    Eigen::Vector3d dp = move("EXX", "EYX", "EZX", "EAX", "EBX", "ECX", r_x) +
                         move("EXY", "EYY", "EZY", "EAY", "EBY", "ECY", r_y) +
                         move("EXZ", "EYZ", "EZZ", "EAZ", "EBZ", "ECZ", r_z);
    dp += Eigen::Vector3d(0.0, 0.0, v("EC0Y")).cross(r_x) * 1e-3;
    dp += Eigen::Vector3d(v("EA0Z"), v("EB0Z"), 0.0).cross(r_y) * 1e-3;
    const Eigen::Vector3d closed = -dp;
    const Eigen::Vector3d model = m.spatialErrorLinearUm(Eigen::Vector3d(x, y, z), e);
    EXPECT_TRUE(model.isApprox(closed, 1e-12)) << model.transpose() << " vs " << closed.transpose();
  }
}

TEST(Multibody, DescriptionErrorsNameTheKey) {
  auto error = [](const char* text) {
    try {
      MultibodyModel::fromJson(nlohmann::json::parse(text), "m.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error(R"({"name": "m", "tool": "t", "workpiece": "bed"})").find("joints: missing"), std::string::npos);
  EXPECT_NE(error(R"({"name": "m", "tool": "t", "workpiece": "bed", "joints": [{"body": "t", "parent": "nowhere"}]})")
                .find("unknown body 'nowhere'"),
            std::string::npos);
  EXPECT_NE(error(R"({"name": "m", "tool": "t", "workpiece": "bed", "joints": [{"body": "t", "parent": "bed",
                      "type": "prismatic", "axis": [1, 1, 0], "coordinate": "x"}]})")
                .find("not a unit vector"),
            std::string::npos);
  EXPECT_NE(error(R"({"name": "m", "tool": "t", "workpiece": "bed", "joints": [{"body": "t", "parent": "bed",
                      "motion_errors": {"EXX": "dw"}}]})")
                .find("joints[0].motion_errors.EXX"),
            std::string::npos);
  EXPECT_NE(error(R"({"name": "m", "tool": "t", "workpiece": "bed", "joints": [{"body": "t", "parent": "bed",
                      "type": "swivel"}]})")
                .find("joints[0].type"),
            std::string::npos);
}

}  // namespace
}  // namespace mtcal::processing
