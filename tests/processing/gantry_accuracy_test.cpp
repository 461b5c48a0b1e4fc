#include "mtcal/processing/gantry_accuracy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>

#include "mtcal/error.h"
#include "mtcal/processing/geometry3d.h"
#include "mtcal/processing/multibody.h"

namespace mtcal::processing {
namespace {

using Eigen::Vector3d;

// Gander, Golub & Strebel, "Least-squares fitting of circles and ellipses", BIT 34 (1994):
// x = [1 2 5 7 9 3], y = [7 6 8 7 5 7] -> centre (4.739782, 2.983533), radius 4.714226 (their
// section 3 example), rms orthogonal residual of that circle 0.452327.
TEST(Geometry3d, CircleInATiltedPlaneMatchesGanderGolubStrebel) {
  const double x[] = {1, 2, 5, 7, 9, 3}, y[] = {7, 6, 8, 7, 5, 7};
  Eigen::Isometry3d place = Eigen::Isometry3d::Identity();
  place.linear() = (Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized())).toRotationMatrix();
  place.translation() = Vector3d(1200, -350, 80);
  Points3d points;
  for (int i = 0; i < 6; ++i) points.push_back(place * Vector3d(x[i], y[i], 0));
  const Circle3dFit fit = fitCircle3d(points);
  EXPECT_LT((fit.centre - place * Vector3d(4.739782, 2.983533, 0)).norm(), 2e-6);
  EXPECT_NEAR(fit.radius_mm, 4.714226, 1e-6);
  EXPECT_NEAR(fit.radial_rms_mm, 0.452327, 1e-6);
  EXPECT_NEAR(fit.plane_rms_mm, 0.0, 1e-9);
  EXPECT_NEAR(std::abs(fit.normal.dot(place.linear().col(2))), 1.0, 1e-12);
}

TEST(Geometry3d, CircleNormalFollowsTheSenseOfRotationAndArcIsReported) {
  Points3d points;
  for (int k = 0; k <= 6; ++k) {
    const double a = k * 10.0 * std::numbers::pi / 180.0;  // 60 deg counter-clockwise about -Y
    points.emplace_back(50.0 * std::cos(a), 0.0, -50.0 * std::sin(a));
  }
  const Circle3dFit fit = fitCircle3d(points);
  EXPECT_LT((fit.normal - Vector3d(0, 1, 0)).norm(), 1e-12);  // x towards -z is a positive turn about +y
  EXPECT_NEAR(fit.arc_deg, 60.0, 1e-9);
  EXPECT_NEAR(fit.radius_mm, 50.0, 1e-9);
  EXPECT_THROW(fitCircle3d({Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(2, 0, 0)}), InputError);
}

TEST(Geometry3d, CommonPerpendicularOfSkewLines) {
  // Closed form: x axis and the line (3, 2 + t, 5 + t): feet (3, 0, 0) and (3, -1.5, 1.5).
  const auto c = commonPerpendicular(Vector3d::Zero(), Vector3d::UnitX(), Vector3d(3, 2, 5), Vector3d(0, 1, 1));
  EXPECT_LT((c.on_first - Vector3d(3, 0, 0)).norm(), 1e-12);
  EXPECT_LT((c.on_second - Vector3d(3, -1.5, 1.5)).norm(), 1e-12);
  EXPECT_NEAR(c.distance_mm, 1.5 * std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(c.angle_deg, 90.0, 1e-12);
  EXPECT_THROW(commonPerpendicular(Vector3d::Zero(), Vector3d::UnitX(), Vector3d(0, 1, 0), Vector3d(-2, 0, 0)),
               InputError);
}

TEST(Geometry3d, PlaneAndLineFits) {
  Points3d plane{{0, 0, 1}, {10, 0, 1}, {0, 10, 1}, {10, 10, 1.2}};
  const PlaneFit p = fitPlane(plane);
  // One corner of a 10 mm square raised by h: the least-squares plane leaves +-h/4 vertically
  // at every corner and slopes h/20 both ways, so the orthogonal rms is (h/4)/sqrt(1 + 2 (h/20)^2)
  // (vertical least squares; the orthogonal fit differs from it by O(h^3)).
  EXPECT_NEAR(p.rms_mm, 0.05 / std::sqrt(1.0 + 2.0 * 0.01 * 0.01), 1e-8);
  EXPECT_THROW(fitPlane({{0, 0, 0}, {1, 1, 1}, {2, 2, 2}}), InputError);
  const LineFit l = fitLine({{5, 1, 1}, {3, 1, 1}, {1, 1, 1}});
  EXPECT_LT((l.direction - Vector3d(-1, 0, 0)).norm(), 1e-12);  // first to last
  EXPECT_NEAR(l.rms_mm, 0.0, 1e-12);
}

// Umeyama, "Least-squares estimation of transformation parameters between two point
// patterns", IEEE PAMI 13(4), 1991, the example of section IV: X = {(0,0), (1,0), (0,2)},
// Y = {(0,0), (-1,0), (0,2)} (a reflection) -> R = [[0.8321, 0.5547], [-0.5547, 0.8321]],
// c = 0.7211, t = (-0.8, 0.4). rigidFit relies on
// Eigen::umeyama never returning a reflection: checked here on the published case.
TEST(Geometry3d, EigenUmeyamaReproducesThePublishedExample) {
  // Dynamic sizes: GCC 12 warns (wrongly) inside Eigen's umeyama for 2 x Dynamic matrices.
  Eigen::MatrixXd x(2, 3), y(2, 3);
  x << 0, 1, 0, 0, 0, 2;
  y << 0, -1, 0, 0, 0, 2;
  const Eigen::MatrixXd t = Eigen::umeyama(x, y, true);
  const double c = t.topLeftCorner(2, 2).col(0).norm();
  const Eigen::Matrix2d r = t.topLeftCorner(2, 2) / c;
  EXPECT_NEAR(r(0, 0), 0.8321, 5e-5);
  EXPECT_NEAR(r(0, 1), 0.5547, 5e-5);
  EXPECT_NEAR(r(1, 0), -0.5547, 5e-5);
  EXPECT_NEAR(r(1, 1), 0.8321, 5e-5);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  EXPECT_NEAR(c, 0.7211, 5e-5);
  EXPECT_NEAR(t(0, 2), -0.8, 1e-12);
  EXPECT_NEAR(t(1, 2), 0.4, 1e-12);
}

TEST(Geometry3d, RigidFitRecoversAMotionAndIgnoresSymmetricRadialErrors) {
  // Points symmetric about their centroid, each moved radially by s_i (opposite points alike):
  // the cross-covariance stays symmetric positive definite, so the least-squares rotation is
  // the identity and the residual of point i is |s_i| |p_i - centroid| (closed form).
  const Points3d from{{100, 0, 0}, {-100, 0, 0}, {0, 60, 0}, {0, -60, 0}, {0, 0, 30}, {0, 0, -30}};
  const double s[] = {0.001, 0.001, -0.002, -0.002, 0.003, 0.003};
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  motion.linear() = Eigen::AngleAxisd(0.4, Vector3d(0.3, -1, 0.2).normalized()).toRotationMatrix();
  motion.translation() = Vector3d(15, -7, 220);
  Points3d to;
  Points3d moved;
  for (int i = 0; i < 6; ++i) {
    to.push_back(motion * (from[static_cast<std::size_t>(i)] * (1.0 + s[i])));
    moved.push_back(motion * from[static_cast<std::size_t>(i)]);
  }
  const RigidFit fit = rigidFit(from, to);
  EXPECT_TRUE(fit.transform.matrix().isApprox(motion.matrix(), 1e-12));
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(fit.residuals_mm[static_cast<std::size_t>(i)],
                std::abs(s[i]) * from[static_cast<std::size_t>(i)].norm(), 1e-10);
  }
  EXPECT_THROW(rigidFit({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}), InputError);
  // The patent's three-point frame equals the rigid motion for undisturbed points.
  const Eigen::Isometry3d t =
      frameFromThreePoints(moved[0], moved[2], moved[4]) * frameFromThreePoints(from[0], from[2], from[4]).inverse();
  EXPECT_TRUE(t.matrix().isApprox(motion.matrix(), 1e-12));
}

// A gantry drilling machine measured by a tracker, synthesised from the multi-body model.
struct Synthetic {
  MultibodyModel model;
  Eigen::VectorXd errors;
  Eigen::Isometry3d tracker_from_bed = Eigen::Isometry3d::Identity();
  double reflector_radius_mm = 19.05;
  std::vector<Vector3d> target_offsets{
      {-100, 60, 200}, {100, 60, 200}, {0, -90, 120}};  // tool frame, from the tool point
  Eigen::VectorXd q0;                                   // initial state

  Synthetic()
      : model(MultibodyModel::fromJson(
            nlohmann::json::parse(
                std::ifstream(std::string(MTCAL_EXAMPLES_DIR) + "/machines/gantry-xyz-ca-cn106017326.model.json")),
            "gantry")),
        errors(Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.terms().size()))),
        q0((Eigen::VectorXd(5) << 0, 1500, 0, 0, 0).finished()) {
    tracker_from_bed.linear() =
        (Eigen::AngleAxisd(0.52, Vector3d::UnitZ()) * Eigen::AngleAxisd(2e-4, Vector3d::UnitX())).toRotationMatrix();
    tracker_from_bed.translation() = Vector3d(-2500, 800, 1100);
  }
  void set(const std::string& name, double value) { errors(model.termIndex(name)) = value; }
  Vector3d seen(const Vector3d& bed_mm) const { return tracker_from_bed * bed_mm; }
  Vector3d actual(const Eigen::VectorXd& q, const Vector3d& offset) const {
    return model.actualPoint(q, errors, model.toolPoint() + offset);
  }
  Eigen::VectorXd pose(double x, double y, double z, double c, double a) const {
    return (Eigen::VectorXd(5) << x, y, z, c, a).finished();
  }

  GantryMeasurements measure(const std::vector<Eigen::VectorXd>& holes) const {
    GantryMeasurements m;
    m.reflector_radius_mm = reflector_radius_mm;
    m.origin_corner = "A";
    // Corner blocks 200 x 200 mm, tops at z = -1200; A's outer faces x = -400, y = -400.
    const Vector3d corners[] = {{-300, -300, 0}, {6300, -300, 0}, {6300, 3300, 0}, {-300, 3300, 0}};
    const char* names[] = {"A", "B", "C", "D"};
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-90.0, 90.0);
    for (int k = 0; k < 4; ++k) {
      BedCorner c;
      c.name = names[k];
      for (int i = 0; i < 5; ++i) {
        c.top.push_back(seen(Vector3d(corners[k].x() + u(rng), corners[k].y() + u(rng), -1200 + reflector_radius_mm)));
      }
      if (k == 0) {
        for (int i = 0; i < 4; ++i) {
          c.side_1.push_back(seen(Vector3d(-400 - reflector_radius_mm, -300 + u(rng), -1300 + u(rng))));
          c.side_2.push_back(seen(Vector3d(-300 + u(rng), -400 - reflector_radius_mm, -1300 + u(rng))));
        }
      }
      m.corners.push_back(c);
    }
    for (int direction : {1, -1}) {
      GantryPass pass;
      pass.direction = direction;
      for (int k = 0; k <= 30; ++k) {
        const double x = direction > 0 ? 200.0 * k : 6000.0 - 200.0 * k;
        pass.points.push_back(seen(actual(pose(x, 1500, 0, 0, 0), target_offsets[0])));
      }
      m.gantry_passes.push_back(pass);
    }
    for (int k = 0; k < 12; ++k) m.c_sweep.push_back(seen(actual(pose(0, 1500, 0, 30.0 * k, 0), target_offsets[0])));
    for (int k = 0; k <= 8; ++k)
      m.a_sweep.push_back(seen(actual(pose(0, 1500, 0, 0, -40.0 + 10.0 * k), target_offsets[0])));
    m.tool_length_mm = 300.0;
    m.tool_point = seen(actual(q0, Vector3d::Zero()));
    for (const auto& t : target_offsets) m.initial_targets.push_back(seen(actual(q0, t)));
    m.initial_np_mm = model.idealPoint(q0);
    for (std::size_t i = 0; i < holes.size(); ++i) {
      HoleMeasurement h;
      h.id = "h" + std::to_string(i + 1);
      h.gantry_position = 1 + static_cast<int>(i % 5);
      h.np_mm = model.idealPoint(holes[i]);
      const Eigen::VectorXd zero = Eigen::VectorXd::Zero(errors.size());
      h.tool_vector = model.actualPoint(holes[i], zero, model.toolPoint() + Vector3d::UnitZ()) - h.np_mm;
      for (const auto& t : target_offsets) h.targets.push_back(seen(actual(holes[i], t)));
      m.holes.push_back(h);
    }
    return m;
  }
  std::vector<Eigen::VectorXd> holes() const {
    std::vector<Eigen::VectorXd> q;
    const double orientations[][2] = {{0, 0}, {20, 0}, {-20, 90}, {15, 45}, {-25, 180}, {10, -60}, {30, 120}};
    for (int i = 0; i < 21; ++i) {
      const auto& o = orientations[i % 7];
      q.push_back(pose(500.0 + 1200.0 * (i % 5), 300.0 + 120.0 * i, 100.0 + 20.0 * (i % 4), o[1], o[0]));
    }
    return q;
  }
  /// dP the evaluation should find: the actual tool point's motion from the initial state in
  /// the global frame minus the programmed motion.
  Vector3d truthUm(const GantryEvaluation& ev, const Eigen::VectorXd& q) const {
    const Eigen::Matrix3d global_from_bed = ev.global_from_tracker.linear() * tracker_from_bed.linear();
    const Vector3d actual_motion = global_from_bed * (actual(q, Vector3d::Zero()) - actual(q0, Vector3d::Zero()));
    return (actual_motion - (model.idealPoint(q) - model.idealPoint(q0))) * 1000.0;
  }
};

TEST(GantryAccuracy, GlobalFrameFromTheBedCornersAndTheGantryLine) {
  Synthetic s;
  s.set("EC0Y", 25.0);  // squareness does not touch the gantry's line
  const GantryMeasurements m = s.measure({});
  const GantryEvaluation ev = evaluateGantry(m);
  // The corner A's outer faces meet the tops at (-400, -400, -1200); the gantry travels along
  // the bed's X exactly here: the global frame is the bed frame moved to that corner.
  for (const Vector3d& p : {Vector3d(-400, -400, -1200), Vector3d(1000, 200, -300), Vector3d(5000, 3000, 0)}) {
    const Vector3d global = ev.global_from_tracker * s.seen(p);
    EXPECT_LT((global - (p - Vector3d(-400, -400, -1200))).norm(), 1e-9) << p.transpose();
  }
  EXPECT_NEAR(ev.gantry_tilt_urad, 0.0, 1e-6);
  EXPECT_NEAR(ev.xy_plane.rms_mm, 0.0, 1e-9);
  // Ideal head: C vertical through the wrist 250 mm under the ram, A along X through it; the
  // squareness shifts the head by 25 urad x 1500 mm = 37.5 um in X.
  EXPECT_NEAR(ev.axes.distance_mm, 0.0, 1e-9);
  EXPECT_NEAR(ev.axes_squareness_urad, 0.0, 1e-6);
  const Vector3d tool_point = s.actual(s.q0, Vector3d::Zero());
  EXPECT_NEAR((tool_point - Vector3d(0, 1500, -550)).norm() * 1000.0, 37.5, 1e-6);
  EXPECT_LT((ev.tcp0_mm - (tool_point - Vector3d(-400, -400, -1200))).norm(), 1e-9);
  EXPECT_EQ(ev.target_fit, "patent-frame");
}

// The inner faces of corner A's block (x = -200, y = -200, towards the bed's centre), touched
// from the bed's side: each face is oriented by its own block, so the origin is their corner
// (-200, -200, -1200), not 2r = 38.1 mm off along both normals as when faces were oriented
// away from the bed's centre.
TEST(GantryAccuracy, InnerFacesTouchedFromTheBedSideGiveTheirCorner) {
  Synthetic s;
  GantryMeasurements m = s.measure({});
  auto& a = m.corners[0];
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-90.0, 90.0);
  a.side_1.clear();
  a.side_2.clear();
  for (int i = 0; i < 4; ++i) {
    a.side_1.push_back(s.seen(Vector3d(-200 + s.reflector_radius_mm, -300 + u(rng), -1300 + u(rng))));
    a.side_2.push_back(s.seen(Vector3d(-300 + u(rng), -200 + s.reflector_radius_mm, -1300 + u(rng))));
  }
  const GantryEvaluation ev = evaluateGantry(m);
  EXPECT_LT((ev.global_from_tracker * s.seen(Vector3d(-200, -200, -1200))).norm(), 1e-9);
}

// What no machine gives is refused with what to check: a pass's direction given the wrong way
// (X and Y mirrored: the holes move against their nominal positions), or a hole's np_mm off by
// 20 mm (a dP of 20 mm).
TEST(GantryAccuracy, ConventionsBrokenInTheFileAreRefused) {
  Synthetic s;
  const GantryMeasurements good = s.measure(s.holes());
  EXPECT_NO_THROW(evaluateGantry(good));
  GantryMeasurements mirrored = good;
  for (auto& pass : mirrored.gantry_passes) pass.direction = -pass.direction;
  try {
    evaluateGantry(mirrored);
    FAIL() << "a mirrored frame was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("moved against their nominal positions"), std::string::npos) << e.what();
  }
  GantryMeasurements typo = good;
  typo.holes[3].np_mm.z() += 20.0;
  try {
    evaluateGantry(typo);
    FAIL() << "a dP of 20 mm was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("dP of 20.0 mm at hole h4"), std::string::npos) << e.what();
  }
}

TEST(GantryAccuracy, AnOutlierOfAGantryPassIsLeftOutOfTheXLine) {
  Synthetic s;
  GantryMeasurements m = s.measure({});
  const GantryEvaluation clean = evaluateGantry(m);
  // Noise across the line (+-2 um, alternating) and one stray point 150 um off.
  for (std::size_t i = 0; i < m.gantry_passes[0].points.size(); ++i) {
    m.gantry_passes[0].points[i] += s.tracker_from_bed.linear() * Vector3d(0, (i % 2 ? 0.002 : -0.002), 0);
  }
  m.gantry_passes[0].points[7] += s.tracker_from_bed.linear() * Vector3d(0, 0.150, 0);
  const GantryEvaluation ev = evaluateGantry(m);
  EXPECT_EQ(ev.gantry_outliers, 1);
  ASSERT_FALSE(ev.notes.empty());
  EXPECT_NE(ev.notes.back().find("outlier"), std::string::npos);
  // The X axis stays where the clean passes put it (the alternating noise tilts it by < 0.1 urad).
  const Eigen::Matrix3d r = ev.global_from_tracker.linear() * clean.global_from_tracker.linear().transpose();
  EXPECT_LT(Eigen::AngleAxisd(r).angle() * 1e6, 0.1);
}

TEST(GantryAccuracy, HoleDeviationsEqualTheModelsTruth) {
  Synthetic s;
  // Linear-axis errors (um, urad), constant: the gantry's line stays straight.
  for (const auto& [name, value] : std::vector<std::pair<std::string, double>>{{"EYX", 6},
                                                                               {"EZX", -4},
                                                                               {"EAX", 12},
                                                                               {"EBX", -9},
                                                                               {"ECX", 7},
                                                                               {"EXY", 3},
                                                                               {"EZY", 5},
                                                                               {"EAY", -8},
                                                                               {"EBY", 10},
                                                                               {"EYZ", -2},
                                                                               {"EC0Y", 25},
                                                                               {"EA0Z", -15},
                                                                               {"EB0Z", 11}}) {
    s.set(name, value);
  }
  const auto holes = s.holes();
  const GantryMeasurements m = s.measure(holes);
  const GantryEvaluation ev = evaluateGantry(m);
  ASSERT_EQ(ev.holes.size(), holes.size());
  double largest = 0.0;
  for (std::size_t i = 0; i < holes.size(); ++i) {
    const Vector3d truth = s.truthUm(ev, holes[i]);
    EXPECT_LT((ev.holes[i].dp_um - truth).norm(), 1e-6) << ev.holes[i].id;
    const Vector3d v = m.holes[i].tool_vector.normalized();
    EXPECT_NEAR(ev.holes[i].dp_perp_um, (truth - v.dot(truth) * v).norm(), 1e-6);
    largest = std::max(largest, truth.norm());
  }
  EXPECT_GT(largest, 20.0);  // the errors are seen, not a vacuous zero
  // Summaries: overall plus one per gantry position, counts add up.
  ASSERT_EQ(ev.summaries.size(), 6u);
  EXPECT_EQ(ev.summaries[0].holes, 21);
  int sum = 0;
  for (std::size_t k = 1; k < ev.summaries.size(); ++k) sum += ev.summaries[k].holes;
  EXPECT_EQ(sum, 21);
  // Least squares on the same three targets gives the same motion when nothing is noisy.
  const GantryEvaluation lsq = evaluateGantry(m, {.target_fit = TargetFit::kLeastSquares});
  for (std::size_t i = 0; i < holes.size(); ++i) EXPECT_LT((lsq.holes[i].dp_um - ev.holes[i].dp_um).norm(), 1e-6);
}

TEST(GantryAccuracy, AxisOffsetMovesThePatentsTcp0AndTheToolPointNestCorrectsIt) {
  Synthetic s;
  s.set("EY0A", 30.0);  // the A axis 30 um beside the C axis: they no longer meet
  const auto holes = s.holes();
  const GantryMeasurements m = s.measure(holes);
  const GantryEvaluation patent = evaluateGantry(m);
  EXPECT_NEAR(patent.axes.distance_mm * 1000.0, 30.0, 1e-6);
  ASSERT_TRUE(patent.tcp0_axes_minus_tool_point_um.has_value());
  EXPECT_NEAR(patent.tcp0_axes_minus_tool_point_um->norm(), 30.0, 1e-6);
  double patent_worst = 0.0;
  for (std::size_t i = 0; i < holes.size(); ++i)
    patent_worst = std::max(patent_worst, (patent.holes[i].dp_um - s.truthUm(patent, holes[i])).norm());
  EXPECT_GT(patent_worst, 10.0);  // a tilted head swings the wrong TCP0 around
  ASSERT_FALSE(patent.notes.empty());
  EXPECT_NE(patent.notes.back().find(
                "TCP0 from the A and C axes is 30.0 um from the tool-point nest (the axes 30.0 um apart"),
            std::string::npos)
      << patent.notes.back();
  const GantryEvaluation measured = evaluateGantry(m, {.tcp0 = Tcp0Source::kToolPoint});
  for (std::size_t i = 0; i < holes.size(); ++i) {
    EXPECT_LT((measured.holes[i].dp_um - s.truthUm(measured, holes[i])).norm(), 1e-6) << measured.holes[i].id;
  }
}

TEST(GantryAccuracy, MoreTargetsUseLeastSquaresAndCollinearTargetsAreWarned) {
  Synthetic s;
  s.target_offsets.push_back({50, 80, 60});
  s.set("EAY", 20);
  const auto holes = s.holes();
  const GantryEvaluation ev = evaluateGantry(s.measure(holes));
  EXPECT_EQ(ev.target_fit, "least-squares");
  for (std::size_t i = 0; i < holes.size(); ++i) {
    EXPECT_LT((ev.holes[i].dp_um - s.truthUm(ev, holes[i])).norm(), 1e-6);
    EXPECT_LT(ev.holes[i].fit_rms_um, 1e-6);
  }
  Synthetic line;
  line.target_offsets = {{-100, 0, 200}, {100, 0, 200}, {0, 2, 200}};
  const GantryEvaluation warned = evaluateGantry(line.measure(line.holes()));
  ASSERT_FALSE(warned.notes.empty());
  EXPECT_NE(warned.notes.back().find("nearly collinear"), std::string::npos);
}

TEST(GantryAccuracy, RefusesMissingOrDegenerateMeasurements) {
  Synthetic s;
  GantryMeasurements m = s.measure(s.holes());
  GantryMeasurements no_corner = m;
  no_corner.origin_corner = "E";
  EXPECT_THROW(evaluateGantry(no_corner), InputError);
  GantryMeasurements short_hole = m;
  short_hole.holes[3].targets.pop_back();
  try {
    evaluateGantry(short_hole);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("hole h4"), std::string::npos) << e.what();
  }
  GantryMeasurements two_corners = m;
  two_corners.corners[2].top.clear();
  two_corners.corners[3].top.clear();
  EXPECT_THROW(evaluateGantry(two_corners), InputError);
  GantryMeasurements no_tool_point = m;
  no_tool_point.tool_point.reset();
  EXPECT_THROW(evaluateGantry(no_tool_point, {.tcp0 = Tcp0Source::kToolPoint}), InputError);
}

TEST(GantryAccuracy, MonteCarloUncertaintyScalesWithTheTrackersMpeAndIsReproducible) {
  Synthetic s;
  const auto holes = s.holes();
  const GantryMeasurements m = s.measure(holes);
  const GantryUncertainty a = monteCarloGantry(m, {}, TrackerMpe{}, 60, 7);
  const GantryUncertainty b = monteCarloGantry(m, {}, TrackerMpe{}, 60, 7);
  ASSERT_EQ(a.holes.size(), holes.size());
  EXPECT_EQ(a.holes[5].dp_sigma_um, b.holes[5].dp_sigma_um);
  EXPECT_GT(a.max_norm_u95_um, 1.0);
  // Halving every MPE term halves every standard deviation (the evaluation is linear in the
  // small disturbances; same seed, same normal draws).
  const TrackerMpe half{5.0, 0.2, 7.5, 3.0};
  const GantryUncertainty h = monteCarloGantry(m, {}, half, 60, 7);
  for (std::size_t i = 0; i < holes.size(); ++i) {
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(h.holes[i].dp_sigma_um(k), a.holes[i].dp_sigma_um(k) / 2.0, 0.01 * a.holes[i].dp_sigma_um(k) + 1e-4);
  }
}

// An independent value for the Monte Carlo U95: the law of propagation of uncertainty (GUM,
// JCGM 100:2008, 5.1.2; JCGM 101:2008, section 8, validates a Monte Carlo result against it
// exactly this way). For errors of micrometres over metres the evaluation is linear in the
// tracker's errors, so dP of a hole is normal with covariance
//   Sigma = sum_p J_p C_p J_p',  C_p = u_d^2 r r' + u_t^2 (I - r r'),
// J_p = d dP / d p (central differences of the evaluation, 1 um steps), r the line of sight
// from the tracker (its origin) to point p, u_d = (MPE_d + MPE_d' R) / 2 and u_t = (MPE_t +
// MPE_t' R) / 2 at range R (the MPE is a 95 % bound: u = MPE / 2, as TrackerMpe states).
// Then sd(dP_k) = sqrt(Sigma_kk), and with |dP| far above its spread (150 to 180 um against a few
// um here: the curvature of the norm changes its spread by (s / |dP|)^2 ~ 1e-3)
//   U95(|dP|) = z_0.975 sqrt(n' Sigma n), n = dP / |dP|, z_0.975 = 1.959964,
// the half-width of the central 95 % interval of a normal; likewise for the part
// perpendicular to the tool axis with w = (I - v v') dP / |(I - v v') dP|.
// Monte Carlo standard errors with N trials, for a normal output of sd s: the sample sd has
// se s / sqrt(2 (N - 1)); a sample p-quantile has variance p (1 - p) / (N f^2) and two of them
// covariance p1 (1 - p2) / (N f1 f2) (the asymptotic joint normality of sample quantiles,
// e.g. David & Nagaraja, Order Statistics, 3rd ed., 2003), so the half-width (q_0.975 - q_0.025) / 2 has
// se s sqrt(2 (0.025 x 0.975 - 0.025^2)) / (2 phi(1.96) sqrt(N)) = 1.865 s / sqrt(N), that is
// 0.951 U95 / sqrt(N). Each Monte Carlo value must lie within 4 of its se (N = 10000: 2.8 %
// for the sd, 3.8 % for U95). Measured: U95(|dP|) 7.14, 9.72, 9.10 um against 7.18, 9.79,
// 9.09 um propagated; perpendicular 7.15, 10.01, 9.45 against 7.18, 10.12, 9.36 um; every sd
// within 0.7 %.
TEST(GantryAccuracy, MonteCarloU95MatchesTheLinearPropagationOfTheTrackersMpe) {
  Synthetic s;
  s.set("EC0Y", 150.0);  // 150 urad x 1200 mm of Y travel from the initial state: 180 um in x
  const std::vector<Eigen::VectorXd> holes{s.pose(500, 300, 100, 0, 0), s.pose(3500, 2700, 150, 90, -20),
                                           s.pose(5300, 420, 60, 45, 25)};
  const GantryMeasurements m = s.measure(holes);
  const TrackerMpe mpe{1.0, 0.04, 1.5, 0.6};  // a tenth of the default: spreads of a few um
  const GantryEvaluation nominal = evaluateGantry(m);
  ASSERT_EQ(nominal.holes.size(), holes.size());

  std::vector<Eigen::Matrix3d> sigma(holes.size(), Eigen::Matrix3d::Zero());
  GantryMeasurements moved = m;
  std::vector<Vector3d*> points;  // the points the Monte Carlo moves
  forEachPoint(moved, [&](Vector3d& p) { points.push_back(&p); });
  const double step_mm = 1e-3;
  for (Vector3d* p : points) {
    const Vector3d at = *p;
    const double range_m = at.norm() / 1000.0;
    const Vector3d r = at.normalized();
    const double u_d_mm = (mpe.distance_um + mpe.distance_um_per_m * range_m) / 2.0 / 1000.0;
    const double u_t_mm = (mpe.transverse_um + mpe.transverse_um_per_m * range_m) / 2.0 / 1000.0;
    const Eigen::Matrix3d rr = r * r.transpose();
    const Eigen::Matrix3d c = u_d_mm * u_d_mm * rr + u_t_mm * u_t_mm * (Eigen::Matrix3d::Identity() - rr);
    std::vector<Eigen::Matrix3d> jac(holes.size());  // um per mm
    for (int k = 0; k < 3; ++k) {
      *p = at + step_mm * Vector3d::Unit(k);
      const GantryEvaluation plus = evaluateGantry(moved);
      *p = at - step_mm * Vector3d::Unit(k);
      const GantryEvaluation minus = evaluateGantry(moved);
      for (std::size_t h = 0; h < holes.size(); ++h) {
        jac[h].col(k) = (plus.holes[h].dp_um - minus.holes[h].dp_um) / (2.0 * step_mm);
      }
    }
    *p = at;
    for (std::size_t h = 0; h < holes.size(); ++h) sigma[h] += jac[h] * c * jac[h].transpose();
  }

  constexpr int kTrials = 10000;
  const GantryUncertainty u = monteCarloGantry(m, {}, mpe, kTrials, 11);
  ASSERT_EQ(u.holes.size(), holes.size());
  constexpr double kZ975 = 1.959964;
  const double se_sd = 1.0 / std::sqrt(2.0 * (kTrials - 1));              // relative
  const double se_u95 = 0.951 / std::sqrt(static_cast<double>(kTrials));  // relative
  for (std::size_t h = 0; h < holes.size(); ++h) {
    const Vector3d dp = nominal.holes[h].dp_um;
    ASSERT_GT(dp.norm(), 100.0) << h;
    for (int k = 0; k < 3; ++k) {
      const double sd = std::sqrt(sigma[h](k, k));
      EXPECT_NEAR(u.holes[h].dp_sigma_um(k), sd, 4.0 * se_sd * sd) << "hole " << h << " component " << k;
    }
    const Vector3d n = dp.normalized();
    const double u95_norm = kZ975 * std::sqrt(n.dot(sigma[h] * n));
    EXPECT_NEAR(u.holes[h].norm_u95_um, u95_norm, 4.0 * se_u95 * u95_norm) << "hole " << h;
    const Vector3d v = m.holes[h].tool_vector.normalized();
    const Vector3d perp = dp - v.dot(dp) * v;
    ASSERT_GT(perp.norm(), 100.0) << h;
    const Vector3d w = perp.normalized();
    const double u95_perp = kZ975 * std::sqrt(w.dot(sigma[h] * w));
    EXPECT_NEAR(u.holes[h].perp_u95_um, u95_perp, 4.0 * se_u95 * u95_perp) << "hole " << h;
  }
}

}  // namespace
}  // namespace mtcal::processing
