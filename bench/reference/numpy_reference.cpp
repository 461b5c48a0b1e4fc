#include "numpy_reference.h"

#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "mtcal/acquisition/error_models.h"
#include "mtcal/acquisition/gantry_measurements.h"

namespace mtcal::reference {
namespace {

const std::string kSourceDir = MTCAL_SOURCE_DIR;

std::string quoted(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string readAll(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Keeps the larger difference (a NaN or infinity on either side counts as infinitely far).
void note(Agreement& a, double mine, double theirs, const std::string& where) {
  double d = std::abs(mine - theirs);
  if (!std::isfinite(d)) d = INFINITY;
  if (a.compared++ == 0 || d > a.max_abs_difference) {
    a.max_abs_difference = d;
    a.worst = fmt::format("{}: mtcal {:.17g}, numpy {:.17g}", where, mine, theirs);
  }
}

bool isNumbers(const nlohmann::json& j, std::size_t n) {
  if (!j.is_array() || j.size() != n) return false;
  for (const auto& v : j) {
    if (!v.is_number()) return false;
  }
  return true;
}

}  // namespace

nlohmann::json runNumpy(const std::string& script, const nlohmann::json& input, const std::vector<std::string>& args) {
  const std::string python = MTCAL_PYTHON;
  if (python.empty()) throw std::runtime_error("no Python 3 interpreter was found when CMake configured the build");
  static std::atomic<int> counter{0};
  const auto stem =
      std::filesystem::temp_directory_path() /
      fmt::format("mtcal_numpy_{}_{}_{}", std::filesystem::path(script).stem().string(), getpid(), counter++);
  const auto input_path = stem.string() + ".json", error_path = stem.string() + ".err";
  std::ofstream(input_path) << input.dump();
  std::string command = quoted(python) + " " + quoted(kSourceDir + "/bench/" + script) + " " + quoted(input_path);
  for (const auto& a : args) command += " " + quoted(a);
  const std::string shown = command;
  command += " 2> " + quoted(error_path);
  std::string out;
  int status = -1;
  if (FILE* pipe = popen(command.c_str(), "r")) {
    char buffer[65536];
    std::size_t n;
    while ((n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) out.append(buffer, n);
    status = pclose(pipe);
  }
  const std::string errors = readAll(error_path);
  std::filesystem::remove(input_path);
  std::filesystem::remove(error_path);
  if (status != 0) {
    throw std::runtime_error(fmt::format("{} failed (status {}): {}", shown,
                                         status >= 0 && WIFEXITED(status) ? WEXITSTATUS(status) : status, errors));
  }
  auto result = nlohmann::json::parse(out, nullptr, false);
  if (!result.is_object())
    throw std::runtime_error(fmt::format("{} printed no JSON object: {}{}", shown, out.substr(0, 200), errors));
  return result;
}

NumpyRun tryRunNumpy(const std::string& script, const nlohmann::json& input, const std::vector<std::string>& args) {
  try {
    return {runNumpy(script, input, args), ""};
  } catch (const std::exception& e) {
    return {nlohmann::json(), e.what()};
  }
}

ModelCase vmc3Model() {
  std::ifstream machine_file(kSourceDir + "/examples/machines/vmc3-cn104200063.model.json");
  auto machine = nlohmann::json::parse(machine_file);
  std::ifstream csv(kSourceDir + "/examples/models/vmc3-error-curves.csv");
  std::vector<processing::ErrorFunction> functions;
  for (const auto& c : acquisition::parseErrorCurvesCsv(csv, "vmc3-error-curves.csv")) {
    functions.push_back(processing::ErrorFunction::fit(c, {}));
  }
  return {processing::ErrorModel(processing::MultibodyModel::fromJson(machine, "vmc3"), functions), machine};
}

std::vector<std::vector<double>> mapGrid(const std::array<int, 3>& points_per_axis) {
  std::vector<std::vector<double>> axes;
  for (int n : points_per_axis) {
    std::vector<double> values;
    for (int i = 0; i < n; ++i) values.push_back(50.0 + 550.0 * i / (n - 1));
    axes.push_back(values);
  }
  return axes;
}

nlohmann::json mapInput(const ModelCase& c, const std::vector<std::vector<double>>& axes) {
  nlohmann::json functions;
  for (const auto& f : c.model.functions()) functions[f.name()] = f.toJson();
  return {{"machine", c.machine}, {"functions", functions}, {"axes", axes}};
}

std::vector<std::string> mapArgs(int repeats, int samples) {
  return {std::to_string(repeats), std::to_string(samples)};
}

Agreement compareMap(const std::vector<Eigen::Vector3d>& mtcal_um, const nlohmann::json& numpy) {
  Agreement a;
  if (!numpy.contains("sample") || !numpy["sample"].is_object()) {
    a.mismatches.push_back("numpy printed no \"sample\" object");
    return a;
  }
  for (const auto& [key, e] : numpy["sample"].items()) {
    const std::size_t index = std::stoul(key);
    if (index >= mtcal_um.size() || !isNumbers(e, 3)) {
      a.mismatches.push_back(
          fmt::format("numpy's point {} is not a point of mtcal's {} or not 3 numbers", key, mtcal_um.size()));
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      note(a, mtcal_um[index](k), e[static_cast<std::size_t>(k)].get<double>(),
           fmt::format("point {} E{}", index, "xyz"[k]));
    }
  }
  return a;
}

std::vector<processing::MeasuredLine> directMethodLines(const processing::ErrorModel& truth) {
  const auto& m = truth.kinematics();
  const Eigen::Vector3d home(300, 200, 150), off(0, 25, 45);
  struct Spec {
    const char* measures;
    int axis, component;
    Eigen::Vector3d offset;
  };
  const std::vector<Spec> specs = {{"EXX", 0, 0, off},
                                   {"EYX", 0, 1, off},
                                   {"EZX", 0, 2, off},
                                   {"EBX", 0, 4, off},
                                   {"ECX", 0, 5, off},
                                   {"EYY", 1, 1, off},
                                   {"EXY", 1, 0, off},
                                   {"EZY", 1, 2, off},
                                   {"EAY", 1, 3, off},
                                   {"ECY", 1, 5, off},
                                   {"EZZ", 2, 2, off},
                                   {"EXZ", 2, 0, off},
                                   {"EYZ", 2, 1, off},
                                   {"EAZ", 2, 3, off},
                                   {"EBZ", 2, 4, off},
                                   {"EZX", 0, 2, Eigen::Vector3d(0, 225, 45)},
                                   {"EZY", 1, 2, Eigen::Vector3d(150, 25, 45)},
                                   {"EXZ", 2, 0, Eigen::Vector3d(0, 125, 45)}};
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.05);
  std::vector<processing::MeasuredLine> out;
  for (const auto& spec : specs) {
    processing::MeasuredLine line;
    line.id = spec.measures;
    line.measures = spec.measures;
    line.coordinate = spec.axis;
    line.q = home;
    line.point_mm = m.toolPoint() + spec.offset;
    line.component = spec.component;
    for (double x = 50.0; x <= 600.0 + 1e-9; x += 20.0) {
      Eigen::VectorXd q = home;
      q(spec.axis) = x;
      const Eigen::VectorXd e = truth.errorsAt(q);
      const Eigen::VectorXd zero = Eigen::VectorXd::Zero(e.size());
      const double reading =
          spec.component < 3
              ? (m.actualPoint(q, e, line.point_mm) - m.actualPoint(q, zero, line.point_mm))(spec.component) * 1000.0
              : m.orientationErrorUrad(q, e)(spec.component - 3);
      line.position_mm.push_back(x);
      line.mean.push_back(reading + noise(rng));
      line.s.push_back(0.3);
      line.repeats.push_back(18);
    }
    out.push_back(std::move(line));
  }
  return out;
}

nlohmann::json identificationInput(const nlohmann::json& machine, const std::vector<processing::MeasuredLine>& lines) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& l : lines) {
    std::vector<double> s;
    for (const auto& v : l.s) s.push_back(v.value());
    out.push_back({{"measures", l.measures},
                   {"coordinate", l.coordinate},
                   {"q", std::vector<double>(l.q.data(), l.q.data() + l.q.size())},
                   {"point_mm", std::vector<double>(l.point_mm.data(), l.point_mm.data() + 3)},
                   {"component", l.component},
                   {"position_mm", l.position_mm},
                   {"mean", l.mean},
                   {"s", s}});
  }
  return {{"machine", machine}, {"lines", out}};
}

Agreement compareIdentification(const processing::LineIdentification& mtcal, const nlohmann::json& numpy) {
  Agreement a;
  if (!numpy.contains("curves") || !numpy["curves"].is_object()) {
    a.mismatches.push_back("numpy printed no \"curves\" object");
    return a;
  }
  const auto& theirs = numpy["curves"];
  for (const auto& c : mtcal.curves) {
    if (!theirs.contains(c.name)) {
      a.mismatches.push_back(c.name + " identified by mtcal only");
      continue;
    }
    const auto& values = theirs[c.name];
    if (!isNumbers(values, c.mean.size())) {
      a.mismatches.push_back(
          fmt::format("{}: mtcal {} node(s), numpy {}", c.name, c.mean.size(),
                      values.is_array() ? fmt::format("{} value(s)", values.size()) : values.dump()));
      continue;
    }
    for (std::size_t n = 0; n < c.mean.size(); ++n)
      note(a, c.mean[n], values[n].get<double>(), fmt::format("{} node {}", c.name, n));
  }
  for (const auto& [name, values] : theirs.items()) {
    bool mine = false;
    for (const auto& c : mtcal.curves) mine = mine || c.name == name;
    if (!mine) a.mismatches.push_back(name + " identified by numpy only");
  }
  return a;
}

const nlohmann::json& gantryExport() {
  static const nlohmann::json j =
      nlohmann::json::parse(std::ifstream(kSourceDir + "/examples/gantry/quick-6x2-export.json"));
  return j;
}

processing::GantryMeasurements gantryMeasurements() {
  return acquisition::measurementsFromJson(gantryExport(), "quick-6x2-export.json");
}

Agreement compareGantry(const processing::GantryEvaluation& mtcal, const nlohmann::json& numpy) {
  Agreement a;
  if (!numpy.contains("dp_um") || !numpy["dp_um"].is_array() || numpy["dp_um"].size() != mtcal.holes.size()) {
    a.mismatches.push_back(fmt::format("mtcal has {} hole(s), numpy's dp_um is {}", mtcal.holes.size(),
                                       numpy.contains("dp_um") ? numpy["dp_um"].dump() : "missing"));
    return a;
  }
  for (std::size_t i = 0; i < mtcal.holes.size(); ++i) {
    const auto& dp = numpy["dp_um"][i];
    if (!isNumbers(dp, 3)) {
      a.mismatches.push_back(fmt::format("numpy's dP of hole {} is not 3 numbers", i + 1));
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      note(a, mtcal.holes[i].dp_um(k), dp[static_cast<std::size_t>(k)].get<double>(),
           fmt::format("hole {} dP{}", i + 1, "xyz"[k]));
    }
  }
  return a;
}

}  // namespace mtcal::reference
