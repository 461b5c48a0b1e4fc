// Writes the camshaft grinder's example files (examples/grinding) from their recipes:
//
//   cam_lift.csv              a cam as a polar lift table: base circle 20 mm, 6 mm lift over
//                             140 deg (20 to 160 deg) with a 1 - cos profile, every degree
//   grinder-error-curves.csv  the error curves of the X + C grinder: C axis 8 um off in X and
//                             -5 um in Y, ECC = 30 + 20 sin c urad every 15 deg, EXX 10 um/m and
//                             ECX 15 urad every 10 mm from 140 to 210 mm
//   c-axis-layout.json        the C-axis ballbar layout: ball A at six places on the work head,
//                             the tailstock ball on the C axis at 150 and 250 mm alternately
//   c-axis-readings.csv       that layout's bar length changes every 15 deg, made through the
//                             grinder's multi-body model (processing::ballbarLengthsMm) from
//                             known C-axis errors, exact (no noise), 6 decimals of um
//
// Usage: mtcal_generate_grinding_examples EXAMPLES_DIR OUT_DIR
// Reads EXAMPLES_DIR/machines/grinder-xc-mks8332a.model.json, writes OUT_DIR/grinding/*.
// The ctest check examples_generated compares the output with the committed files.

#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "mtcal/processing/ballbar_identification.h"
#include "mtcal/processing/multibody.h"

namespace {

using namespace mtcal;

constexpr double kDeg = std::numbers::pi / 180.0;

std::ofstream create(const std::filesystem::path& path) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error("cannot write " + path.string());
  return out;
}

// Base circle 20 mm; from 20 to 160 deg the lift rises and falls as 3 (1 - cos) to 6 mm at 90 deg.
void writeCamLift(const std::filesystem::path& dir) {
  constexpr double kBaseRadiusMm = 20.0, kLiftMm = 6.0, kLiftStartDeg = 20.0, kLiftSpanDeg = 140.0;
  auto out = create(dir / "cam_lift.csv");
  out << "# mtcal example: a cam as a polar lift table (base circle 20 mm, 6 mm lift over 140 deg, 1 - cos)\n"
         "angle_deg,radius_mm\n";
  for (int angle_deg = 0; angle_deg < 360; ++angle_deg) {
    const double u = (angle_deg - kLiftStartDeg) / kLiftSpanDeg;  // 0 to 1 over the lift
    const double lift_mm = u > 0.0 && u < 1.0 ? kLiftMm / 2.0 * (1.0 - std::cos(2.0 * std::numbers::pi * u)) : 0.0;
    out << fmt::format("{},{:.6f}\n", angle_deg, kBaseRadiusMm + lift_mm);
  }
}

void writeErrorCurves(const std::filesystem::path& dir) {
  auto out = create(dir / "grinder-error-curves.csv");
  out << "# mtcal example: error curves of an X + C camshaft grinder "
         "(examples/machines/grinder-xc-mks8332a.model.json)\n"
         "# C axis 8 um off in X and -5 um in Y, its angular positioning 30 + 20 sin(c) urad, X positioning 10 um/m, X "
         "yaw 15 urad\n"
         "error,position_mm,value\n";
  out << fmt::format("EX0C,,{}\n", 8.0) << fmt::format("EY0C,,{}\n", -5.0);
  for (int c_deg = 0; c_deg <= 360; c_deg += 15) {
    out << fmt::format("ECC,{},{:.4f}\n", c_deg, 30.0 + 20.0 * std::sin(c_deg * kDeg));
  }
  constexpr double kPositioningUmPerMm = 10.0 / 1000.0;  // 10 um/m
  for (int x_mm = 140; x_mm <= 210; x_mm += 10) out << fmt::format("EXX,{},{:.4f}\n", x_mm, kPositioningUmPerMm * x_mm);
  for (int x_mm = 140; x_mm <= 210; x_mm += 10) out << fmt::format("ECX,{},{}\n", x_mm, 15.0);
}

// The C-axis layout of docs/grinding.md: ball A on the work head (workpiece frame), the
// tailstock ball on the C axis at 150 and 250 mm alternately (one height alone cannot tell the
// head's tilts from its translations).
processing::BallbarSetup cAxisLayout() {
  const std::vector<Eigen::Vector3d> head_balls_mm{{50, 0, 0},    {0, 50, 10},   {-40, 30, 20},
                                                   {30, -40, 60}, {50, 20, 100}, {-20, -50, 80}};
  processing::BallbarSetup setup;
  setup.coordinate = "c";
  for (std::size_t i = 0; i < head_balls_mm.size(); ++i) {
    setup.pairs.push_back({Eigen::Vector3d(0, 0, i % 2 == 0 ? 150.0 : 250.0), head_balls_mm[i]});
  }
  return setup;
}

void writeLayout(const std::filesystem::path& dir, const processing::BallbarSetup& setup) {
  auto out = create(dir / "c-axis-layout.json");
  auto vector = [](const Eigen::Vector3d& v) { return fmt::format("[{}, {}, {}]", v.x(), v.y(), v.z()); };
  out << "{\n"
         "  \"comment\": \"C-axis ballbar test of the camshaft grinder: ball A on the work head at six places "
         "(workpiece "
         "frame), ball B on the tailstock centre, on the C axis, at 150 and 250 mm alternately (one height alone "
         "cannot "
         "tell the head's tilts from its translations, docs/grinding.md)\",\n"
      << "  \"coordinate\": \"" << setup.coordinate << "\",\n"
      << "  \"pairs\": [\n";
  for (std::size_t i = 0; i < setup.pairs.size(); ++i) {
    out << fmt::format("    {{\"tool_ball_mm\": {}, \"work_ball_mm\": {}}}{}\n", vector(setup.pairs[i].tool_ball_mm),
                       vector(setup.pairs[i].work_ball_mm), i + 1 < setup.pairs.size() ? "," : "");
  }
  out << "  ]\n}\n";
}

// The C axis' motion errors (um, urad) at c (deg); all zero at 0, the reference position.
double cAxisError(const std::string& term, double c_deg) {
  const double c = c_deg * kDeg;
  if (term == "EXC") return 3.0 * std::sin(c);
  if (term == "EYC") return 2.0 * (std::cos(c) - 1.0);
  if (term == "EZC") return 1.5 * std::sin(2.0 * c);
  if (term == "EAC") return 5.0 * std::sin(c);
  if (term == "EBC") return 4.0 * (1.0 - std::cos(c));
  if (term == "ECC") return 10.0 * std::sin(c);
  return 0.0;
}

void writeReadings(const std::filesystem::path& dir, const processing::MultibodyModel& grinder,
                   const processing::BallbarSetup& setup) {
  auto out = create(dir / "c-axis-readings.csv");
  out << "# mtcal example: ballbar length changes of the C-axis layout c-axis-layout.json, made through the grinder "
         "model from\n"
         "# EXC = 3 sin c, EYC = 2 (cos c - 1), EZC = 1.5 sin 2c um, EAC = 5 sin c, EBC = 4 (1 - cos c), ECC = 10 sin "
         "c "
         "urad\n"
         "position,pair,delta_length_um\n";
  std::vector<double> reference_mm;
  for (int c_deg = 0; c_deg < 360; c_deg += 15) {
    Eigen::VectorXd errors(static_cast<Eigen::Index>(grinder.terms().size()));
    for (std::size_t t = 0; t < grinder.terms().size(); ++t) {
      errors(static_cast<Eigen::Index>(t)) = cAxisError(grinder.terms()[t].name, c_deg);
    }
    const auto lengths_mm = processing::ballbarLengthsMm(grinder, setup, c_deg, errors, Eigen::Vector2d::Zero());
    if (reference_mm.empty()) reference_mm = lengths_mm;  // the bar zeroed at the first position
    for (std::size_t p = 0; p < lengths_mm.size(); ++p) {
      out << fmt::format("{},{},{:.6f}\n", c_deg, p + 1, (lengths_mm[p] - reference_mm[p]) * 1000.0);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: " << argv[0] << " EXAMPLES_DIR OUT_DIR\n";
    return 2;
  }
  try {
    const std::filesystem::path examples = argv[1], dir = std::filesystem::path(argv[2]) / "grinding";
    std::filesystem::create_directories(dir);
    std::ifstream machine_file(examples / "machines" / "grinder-xc-mks8332a.model.json");
    if (!machine_file) throw std::runtime_error("cannot read the grinder model in " + examples.string() + "/machines");
    const auto grinder =
        processing::MultibodyModel::fromJson(nlohmann::json::parse(machine_file), "grinder-xc-mks8332a");
    writeCamLift(dir);
    writeErrorCurves(dir);
    const auto layout = cAxisLayout();
    writeLayout(dir, layout);
    writeReadings(dir, grinder, layout);
  } catch (const std::exception& e) {
    std::cerr << argv[0] << ": " << e.what() << "\n";
    return 1;
  }
  return 0;
}
