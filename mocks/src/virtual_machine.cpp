#include "mtcal/mocks/virtual_machine.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "mtcal/error.h"
#include "mtcal/mocks/default_kinematics.h"
#include "mtcal/mocks/random.h"

namespace mtcal::mocks {
namespace {

constexpr std::uint64_t kScatterStream = 1;

[[noreturn]] void bad(const std::string& source, const std::string& key, const std::string& why) {
  throw InputError(source + ": " + key + ": " + why);
}

double number(const nlohmann::json& j, const char* key, double fallback, const std::string& source,
              const std::string& path) {
  if (!j.contains(key)) return fallback;
  if (!j[key].is_number()) bad(source, path + key, "must be a number");
  return j[key].get<double>();
}

ErrorCurve curveFromJson(const nlohmann::json& j, const std::string& source, const std::string& path) {
  ErrorCurve c;
  if (!j.is_object()) bad(source, path, "must be an object with 'poly' and/or 'harmonics'");
  for (const auto& [key, value] : j.items()) {
    if (key == "poly") {
      if (!value.is_array()) bad(source, path + ".poly", "must be an array of numbers");
      for (const auto& v : value) {
        if (!v.is_number()) bad(source, path + ".poly", "must be an array of numbers");
        c.poly.push_back(v.get<double>());
      }
    } else if (key == "harmonics") {
      if (!value.is_array()) bad(source, path + ".harmonics", "must be an array");
      for (std::size_t i = 0; i < value.size(); ++i) {
        const std::string hp = path + ".harmonics[" + std::to_string(i) + "].";
        ErrorCurve::Harmonic h;
        h.amplitude = number(value[i], "amplitude", 0.0, source, hp);
        h.period_mm = number(value[i], "period_mm", 0.0, source, hp);
        h.phase_rad = number(value[i], "phase_rad", 0.0, source, hp);
        if (!(h.period_mm > 0.0)) bad(source, hp + "period_mm", "must be > 0");
        c.harmonics.push_back(h);
      }
    } else {
      bad(source, path + "." + key, "unknown key (expected poly, harmonics)");
    }
  }
  return c;
}

}  // namespace

double ErrorCurve::value(double pos_mm) const {
  const double p_m = pos_mm / 1000.0;
  double v = 0.0;
  for (auto it = poly.rbegin(); it != poly.rend(); ++it) v = v * p_m + *it;
  for (const auto& h : harmonics)
    v += h.amplitude * std::sin(2.0 * std::numbers::pi * pos_mm / h.period_mm + h.phase_rad);
  return v;
}

Axis parseAxis(const std::string& name) {
  if (name == "X" || name == "x") return Axis::kX;
  if (name == "Y" || name == "y") return Axis::kY;
  if (name == "Z" || name == "z") return Axis::kZ;
  throw InputError("axis '" + name + "' is not one of X, Y, Z");
}

const char* axisName(Axis axis) { return axis == Axis::kX ? "X" : axis == Axis::kY ? "Y" : "Z"; }

VirtualMachineConfig VirtualMachineConfig::fromJson(const nlohmann::json& j, const std::string& source) {
  VirtualMachineConfig c;
  if (!j.is_object()) bad(source, "(top level)", "must be a JSON object");
  std::map<std::string, std::string> axis_of_error;  // motion errors by the axis that lists them
  for (const auto& [key, value] : j.items()) {
    if (key == "name") {
      if (!value.is_string()) bad(source, key, "must be a string");
      c.name = value.get<std::string>();
    } else if (key == "seed") {
      if (!value.is_number_unsigned()) bad(source, key, "must be a non-negative integer");
      c.seed = value.get<std::uint64_t>();
    } else if (key == "axes") {
      if (!value.is_object()) bad(source, key, "must be an object keyed by X, Y, Z");
      // An axis' "errors": true error curves by ISO 230-1 name.
      const auto readErrors = [&](const nlohmann::json& errors, const std::string& axis_name) {
        const std::string path = "axes." + axis_name + ".errors";
        if (!errors.is_object()) bad(source, path, "must be an object keyed by ISO 230-1 names");
        for (const auto& [ename, curve] : errors.items()) {
          c.errors[ename] = curveFromJson(curve, source, path + "." + ename);
          axis_of_error[ename] = axis_name;
        }
      };
      for (const auto& [axis_name, a] : value.items()) {
        if (axis_name == "A" || axis_name == "B" || axis_name == "C") {  // rotary: errors only
          if (!a.is_object()) bad(source, "axes." + axis_name, "must be an object");
          for (const auto& [akey, avalue] : a.items()) {
            if (akey != "errors")
              bad(source, "axes." + axis_name + "." + akey, "unknown key (a rotary axis has only errors)");
            readErrors(avalue, axis_name);
          }
          continue;
        }
        Axis axis;
        try {
          axis = parseAxis(axis_name);
        } catch (const InputError& e) {
          bad(source, "axes." + axis_name, e.what());
        }
        AxisDrive& m = c.axes[static_cast<int>(axis)];
        const std::string path = "axes." + axis_name + ".";
        for (const auto& [akey, avalue] : a.items()) {
          if (akey == "errors") {
            readErrors(avalue, axis_name);
          } else if (akey != "min_mm" && akey != "max_mm" && akey != "backlash_um" && akey != "positioning_sigma_um" &&
                     akey != "kv_per_s" && akey != "reversal_spike_um" && akey != "reversal_spike_decay_s") {
            bad(source, path + akey,
                "unknown key (expected min_mm, max_mm, backlash_um, positioning_sigma_um, kv_per_s, reversal_spike_um, "
                "reversal_spike_decay_s, errors)");
          }
        }
        m.min_mm = number(a, "min_mm", m.min_mm, source, path);
        m.max_mm = number(a, "max_mm", m.max_mm, source, path);
        m.backlash_um = number(a, "backlash_um", 0.0, source, path);
        m.positioning_sigma_um = number(a, "positioning_sigma_um", 0.0, source, path);
        m.kv_per_s = number(a, "kv_per_s", 0.0, source, path);
        m.reversal_spike_um = number(a, "reversal_spike_um", 0.0, source, path);
        m.reversal_spike_decay_s = number(a, "reversal_spike_decay_s", m.reversal_spike_decay_s, source, path);
        if (!(m.max_mm > m.min_mm)) bad(source, path + "max_mm", "must be greater than min_mm");
        if (m.kv_per_s < 0.0) bad(source, path + "kv_per_s", "must be >= 0 (0: ideal servo)");
        if (!(m.reversal_spike_decay_s > 0.0)) bad(source, path + "reversal_spike_decay_s", "must be > 0");
        if (m.positioning_sigma_um < 0.0) bad(source, path + "positioning_sigma_um", "must be >= 0");
      }
    } else if (key == "squareness" || key == "static_errors") {
      if (!value.is_object()) bad(source, key, "must be an object of ISO 230-1 names to um or urad");
      for (const auto& [name, urad] : value.items()) {
        if (!urad.is_number()) bad(source, key + "." + name, "must be a number (um or urad)");
        c.errors[name] = ErrorCurve{{urad.get<double>()}, {}};
      }
    } else if (key == "kinematics") {
      if (value.is_string()) {
        const auto path = std::filesystem::path(source).parent_path() / value.get<std::string>();
        std::ifstream in(path);
        if (!in) bad(source, key, "cannot read the model file " + path.string());
        try {
          c.kinematics_json = nlohmann::json::parse(in).dump();
        } catch (const nlohmann::json::exception& e) {
          bad(source, key, path.string() + " is not JSON: " + e.what());
        }
      } else if (value.is_object()) {
        c.kinematics_json = value.dump();
      } else {
        bad(source, key, "must be a machine description object or the name of a model file (docs/multibody-model.md)");
      }
    } else if (key == "thermal") {
      c.thermal = MachineThermalConfig::fromJson(value, source);
    } else if (key != "settle_time_constant_s" && key != "feed_mm_per_min" && key != "rotary_speed_deg_per_s" &&
               key != "expansion_per_k" && key != "material_temp_c" && key != "air_temp_c" &&
               key != "air_pressure_pa" && key != "humidity_pct") {
      bad(source, key, "unknown key");
    }
  }
  c.settle_time_constant_s = number(j, "settle_time_constant_s", c.settle_time_constant_s, source, "");
  c.feed_mm_per_min = number(j, "feed_mm_per_min", c.feed_mm_per_min, source, "");
  c.rotary_speed_deg_per_s = number(j, "rotary_speed_deg_per_s", c.rotary_speed_deg_per_s, source, "");
  if (!(c.rotary_speed_deg_per_s > 0.0)) bad(source, "rotary_speed_deg_per_s", "must be > 0");
  c.expansion_per_k = number(j, "expansion_per_k", c.expansion_per_k, source, "");
  c.material_temp_c = number(j, "material_temp_c", c.material_temp_c, source, "");
  c.air_temp_c = number(j, "air_temp_c", c.air_temp_c, source, "");
  c.air_pressure_pa = number(j, "air_pressure_pa", c.air_pressure_pa, source, "");
  c.humidity_pct = number(j, "humidity_pct", c.humidity_pct, source, "");
  if (!(c.feed_mm_per_min > 0.0)) bad(source, "feed_mm_per_min", "must be > 0");
  if (c.settle_time_constant_s < 0.0) bad(source, "settle_time_constant_s", "must be >= 0");
  try {
    const auto model = c.kinematics();
    for (const auto& [name, curve] : c.errors) {
      const auto& term = model.terms()[static_cast<std::size_t>(model.termIndex(name))];
      const auto axis = axis_of_error.find(name);
      const bool listed_as_motion = axis != axis_of_error.end();
      if (term.motion != listed_as_motion) {
        bad(source, listed_as_motion ? "axes." + axis->second + ".errors." + name : "static_errors." + name,
            term.motion ? "a motion error: list it under the axes" : "a static error: list it under static_errors");
      }
      if (listed_as_motion) {
        const int coordinate = model.coordinateOfJoint(term.joint);
        std::string coordinate_name = model.coordinates()[static_cast<std::size_t>(coordinate)];
        std::string axis_lower = axis->second;
        for (auto& ch : axis_lower) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
        if (coordinate_name != axis_lower) {
          bad(source, "axes." + axis->second + ".errors." + name,
              "not an error of axis " + axis->second + " (it moves with coordinate " + coordinate_name + ")");
        }
      }
    }
  } catch (const InputError& e) {
    throw InputError(source + ": " + e.what());
  }
  return c;
}

processing::MultibodyModel VirtualMachineConfig::kinematics() const {
  if (kinematics_json.empty()) {
    return processing::MultibodyModel::fromJson(nlohmann::json::parse(kDefaultKinematicsJson),
                                                "built-in kinematics (vmc3-cn104200063.model.json)");
  }
  return processing::MultibodyModel::fromJson(nlohmann::json::parse(kinematics_json), "kinematics");
}

double VirtualMachineConfig::trueError(const std::string& name, double coordinate) const {
  const auto it = errors.find(name);
  return it == errors.end() ? 0.0 : it->second.value(coordinate);
}

VirtualMachineConfig VirtualMachineConfig::demo(std::uint64_t seed) {
  VirtualMachineConfig c;
  c.name = "virtual-vmc";
  c.seed = seed;
  for (auto& a : c.axes) {
    a.min_mm = 0.0;
    a.max_mm = 700.0;
    a.positioning_sigma_um = 0.6;
    a.backlash_um = 2.5;
    a.reversal_spike_decay_s = 0.015;
  }
  // Contouring (followPath, circular tests): slightly mismatched position loops and a stick
  // at X and Y reversals.
  c.axes[0].kv_per_s = 30.0;
  c.axes[1].kv_per_s = 30.5;
  c.axes[2].kv_per_s = 30.0;
  c.axes[0].reversal_spike_um = 1.5;
  c.axes[1].reversal_spike_um = 1.0;
  // EXX: a slow scale error with a bow and a 180 mm undulation (um; poly in um/m^k).
  c.errors["EXX"] = {{0.0, 9.0, -7.0}, {{1.2, 180.0, 0.4}}};
  c.errors["EYX"] = {{0.0, -2.0, 6.0}, {}};    // straightness
  c.errors["EZX"] = {{0.0, 3.0, -4.0}, {}};    // straightness
  c.errors["EAX"] = {{0.0, 4.0}, {}};          // roll
  c.errors["EBX"] = {{0.0, 18.0, -8.0}, {}};   // pitch
  c.errors["ECX"] = {{1.0, -10.0, 14.0}, {}};  // yaw
  c.errors["EYY"] = {{0.0, -6.0, 4.0}, {}};
  c.errors["EZZ"] = {{0.0, 5.0, 3.0}, {}};
  c.errors["EC0Y"] = {{12.0}, {}};
  c.errors["EB0Z"] = {{-8.0}, {}};
  c.errors["EA0Z"] = {{5.0}, {}};
  c.material_temp_c = 20.6;
  c.air_temp_c = 20.4;
  c.air_pressure_pa = 100650.0;
  c.humidity_pct = 42.0;
  return c;
}

VirtualMachine::VirtualMachine(VirtualMachineConfig config, WorldClock& clock)
    : config_(std::move(config)), model_(config_.kinematics()), clock_(clock) {
  const auto& coords = model_.coordinates();
  for (int a = 0; a < 3; ++a) {
    const std::string name(1, static_cast<char>('x' + a));
    const auto it = std::find(coords.begin(), coords.end(), name);
    if (it == coords.end()) throw InputError("machine '" + model_.name() + "' has no coordinate " + name);
    coordinate_of_axis_[a] = static_cast<int>(it - coords.begin());
    positioning_term_[a] = -1;
    commanded_[a] = config_.axes[a].min_mm;
  }
  rotary_commanded_deg_.assign(coords.size(), 0.0);
  if (config_.thermal) thermal_ = std::make_unique<MachineThermal>(*config_.thermal);
  for (const auto& [name, curve] : config_.errors) model_.termIndex(name);  // throws for an unknown name
  for (std::size_t t = 0; t < model_.terms().size(); ++t) {
    const auto& term = model_.terms()[t];
    const auto it = config_.errors.find(term.name);
    curve_of_term_.push_back(it == config_.errors.end() ? nullptr : &it->second);
    coordinate_of_term_.push_back(term.motion ? model_.coordinateOfJoint(term.joint) : -1);
    const auto& joint = model_.joints()[static_cast<std::size_t>(term.joint)];
    if (!term.motion || joint.type != processing::JointType::kPrismatic) continue;
    Eigen::Index along = 0;
    joint.axis.cwiseAbs().maxCoeff(&along);
    if (static_cast<int>(term.component) != along) continue;
    for (int a = 0; a < 3; ++a) {
      if (coordinate_of_term_.back() == coordinate_of_axis_[a]) positioning_term_[a] = static_cast<int>(t);
    }
  }
  for (int a = 0; a < 3; ++a) {
    if (positioning_term_[a] < 0) {
      throw InputError("machine '" + model_.name() + "': axis " + axisName(static_cast<Axis>(a)) +
                       " has no positioning error term (a motion error along its axis)");
    }
  }
  std::array<double, 3> check{};
  addVolumetric(Eigen::VectorXd::Zero(static_cast<Eigen::Index>(coords.size())),
                check);  // throws for a term the machine lacks
}

double VirtualMachine::moveTo(Axis axis, double target_mm) {
  const auto& drive = config_.axes[static_cast<int>(axis)];
  if (!drive.reaches(target_mm)) {
    throw InputError(std::string("move of ") + axisName(axis) + " to " + std::to_string(target_mm) +
                     " mm is outside the travel [" + std::to_string(drive.min_mm) + ", " +
                     std::to_string(drive.max_mm) + "]");
  }
  std::lock_guard lock(mutex_);
  const int ai = static_cast<int>(axis);
  Move m;
  m.index = moves_.size();
  m.axis = axis;
  m.from_mm = commanded_[ai];
  m.to_mm = target_mm;
  m.direction = target_mm > m.from_mm ? 1 : target_mm < m.from_mm ? -1 : 0;
  if (m.direction != 0) last_direction_[ai] = m.direction;
  m.direction = last_direction_[ai];
  m.scatter_um =
      drive.positioning_sigma_um * normalFromKey(config_.seed, kScatterStream + (config_.session << 8), m.index);
  m.start_time_s = clock_.nowS();
  m.done_time_s = m.start_time_s + std::abs(m.to_mm - m.from_mm) / (config_.feed_mm_per_min / 60.0);
  // The machine is at rest when every axis' last move is done (a move supersedes the earlier
  // moves of its own axis).
  last_done_s_[ai] = m.done_time_s;
  m.machine_done_s = std::max(*std::max_element(last_done_s_.begin(), last_done_s_.end()), last_rotary_done_s_);
  commanded_[ai] = target_mm;
  moved_[ai] = true;
  moves_.push_back(m);
  return m.done_time_s;
}

double VirtualMachine::rotateTo(const std::string& coordinate, double angle_deg) {
  const auto& coords = model_.coordinates();
  const auto it = std::find(coords.begin(), coords.end(), coordinate);
  const int index = static_cast<int>(it - coords.begin());
  if (it == coords.end() ||
      std::find(coordinate_of_axis_.begin(), coordinate_of_axis_.end(), index) != coordinate_of_axis_.end()) {
    throw InputError("machine '" + model_.name() + "' has no rotary axis '" + coordinate + "'");
  }
  if (!std::isfinite(angle_deg)) throw InputError("rotary move of " + coordinate + " to a non-finite angle");
  std::lock_guard lock(mutex_);
  Move m;
  m.index = moves_.size();
  m.rotary = index;
  m.from_mm = rotary_commanded_deg_[static_cast<std::size_t>(index)];
  m.to_mm = angle_deg;
  m.direction = 1;
  m.scatter_um = 0.0;
  m.start_time_s = clock_.nowS();
  m.done_time_s = m.start_time_s + std::abs(m.to_mm - m.from_mm) / config_.rotary_speed_deg_per_s;
  last_rotary_done_s_ = std::max(last_rotary_done_s_, m.done_time_s);
  m.machine_done_s = std::max(*std::max_element(last_done_s_.begin(), last_done_s_.end()), last_rotary_done_s_);
  rotary_commanded_deg_[static_cast<std::size_t>(index)] = angle_deg;
  moves_.push_back(m);
  return m.done_time_s;
}

std::pair<double, double> VirtualMachine::followPath(const processing::ContourPath& path) {
  constexpr double kDt = 0.001;  // the interpolator's cycle
  const Eigen::Vector3d start = path.start();
  const auto steps = static_cast<std::size_t>(std::ceil(path.durationS() / kDt));
  double tail_s = 0.0;  // until every transient is below 2e-9 of its size
  for (const auto& a : config_.axes) {
    if (a.kv_per_s > 0.0) tail_s = std::max(tail_s, 20.0 / a.kv_per_s);
    if (a.reversal_spike_um > 0.0) tail_s = std::max(tail_s, 20.0 * a.reversal_spike_decay_s);
  }
  const std::size_t total = steps + static_cast<std::size_t>(std::ceil(tail_s / kDt)) + 2;
  Contour c;
  c.dt_s = kDt;
  c.position_mm.resize(total);
  c.drive_um.resize(total);
  std::vector<Eigen::Vector3d> command(total);
  for (std::size_t k = 0; k < total; ++k) {
    command[k] = path.positionAt(static_cast<double>(k) * kDt);
    for (int a = 0; a < 3; ++a) {
      const auto& drive = config_.axes[a];
      if (command[k](a) < drive.min_mm - 1e-9 || command[k](a) > drive.max_mm + 1e-9) {
        throw InputError(fmt::format("path leaves the travel of {} at {:.3f} s: {:.4f} mm outside [{}, {}]",
                                     axisName(static_cast<Axis>(a)), static_cast<double>(k) * kDt, command[k](a),
                                     drive.min_mm, drive.max_mm));
      }
    }
  }
  std::lock_guard lock(mutex_);
  for (int a = 0; a < 3; ++a) {
    if (std::abs(commanded_[a] - start(a)) > 1e-6) {
      throw InputError(fmt::format("path starts with {} at {} mm but the axis is at {} mm",
                                   axisName(static_cast<Axis>(a)), start(a), commanded_[a]));
    }
  }
  for (int a = 0; a < 3; ++a) {
    const auto& drive = config_.axes[a];
    const double half_play_um = drive.backlash_um / 2.0;
    double motor = start(a);
    double play_um = -last_direction_[a] * half_play_um;  // the table's offset from the motor
    int moving = last_direction_[a], commanded_direction = last_direction_[a];
    double since_reversal_s = 1e300;
    for (std::size_t k = 0; k < total; ++k) {
      const double previous = motor;
      if (k > 0 && drive.kv_per_s > 0.0) {
        // First-order loop, exact for a command linear over the cycle.
        const double v = (command[k](a) - command[k - 1](a)) / kDt, lag = v / drive.kv_per_s;
        motor = command[k](a) - lag + (motor - command[k - 1](a) + lag) * std::exp(-drive.kv_per_s * kDt);
      } else {
        motor = command[k](a);
      }
      const double step_um = (motor - previous) * 1000.0;
      if (std::abs(step_um) > 1e-9) {
        const int now_moving = step_um > 0.0 ? 1 : -1;
        if (now_moving != moving && k > 0) since_reversal_s = 0.0;
        moving = now_moving;
      }
      play_um = std::clamp(play_um - step_um, -half_play_um, half_play_um);  // the table waits inside the play
      const double stick_um =
          drive.reversal_spike_um > 0.0 && since_reversal_s < 1e299
              ? -moving * drive.reversal_spike_um * std::exp(-since_reversal_s / drive.reversal_spike_decay_s)
              : 0.0;
      // The controller's compensation follows the commanded direction (the last one while the command stands).
      if (k > 0 && command[k](a) != command[k - 1](a)) commanded_direction = command[k](a) > command[k - 1](a) ? 1 : -1;
      c.position_mm[k][static_cast<std::size_t>(a)] = motor;
      c.drive_um[k][static_cast<std::size_t>(a)] =
          play_um + stick_um + compensationUm(a, command[k](a), commanded_direction);
      since_reversal_s += kDt;
    }
    last_direction_[a] = moving;
  }
  c.start_s = std::ceil(clock_.nowS() / 0.1 - 1e-9) * 0.1;
  const double end_s = c.start_s + static_cast<double>(total - 1) * kDt;
  contours_.push_back(std::move(c));
  const Eigen::Vector3d end = path.end();
  for (int a = 0; a < 3; ++a) {
    Move m;
    m.index = moves_.size();
    m.axis = static_cast<Axis>(a);
    m.start_time_s = contours_.back().start_s;
    m.done_time_s = end_s;
    m.from_mm = start(a);
    m.to_mm = end(a);
    m.direction = last_direction_[a];
    m.scatter_um = 0.0;
    m.contour = static_cast<int>(contours_.size() - 1);
    last_done_s_[a] = end_s;
    m.machine_done_s = end_s;
    commanded_[a] = end(a);
    moved_[a] = true;
    moves_.push_back(m);
  }
  return {contours_.back().start_s, end_s};
}

std::array<double, 3> VirtualMachine::commanded() const {
  std::lock_guard lock(mutex_);
  return commanded_;
}

std::array<double, 3> VirtualMachine::positionsAt(double t_s) const {
  std::lock_guard lock(mutex_);
  const State s = stateAt(t_s, false);
  return {s.q(coordinate_of_axis_[0]), s.q(coordinate_of_axis_[1]), s.q(coordinate_of_axis_[2])};
}

std::uint64_t VirtualMachine::moveCount() const {
  std::lock_guard lock(mutex_);
  return moves_.size();
}

std::pair<std::uint64_t, double> VirtualMachine::moveEpoch(double t_s) const {
  std::lock_guard lock(mutex_);
  const Move* move = lastMoveStarted(t_s);
  return move ? std::pair{move->index + 1, move->machine_done_s} : std::pair{std::uint64_t{0}, 0.0};
}

const VirtualMachine::Move* VirtualMachine::lastMoveStarted(double t_s) const {
  for (auto it = moves_.rbegin(); it != moves_.rend(); ++it) {
    if (it->start_time_s <= t_s) return &*it;
  }
  return nullptr;
}

const VirtualMachine::Move* VirtualMachine::lastMoveBefore(Axis axis, double t_s) const {
  for (auto it = moves_.rbegin(); it != moves_.rend(); ++it) {
    if (it->rotary < 0 && it->axis == axis && it->start_time_s <= t_s) return &*it;
  }
  return nullptr;
}

const VirtualMachine::Move* VirtualMachine::lastRotaryMoveBefore(int coordinate, double t_s) const {
  for (auto it = moves_.rbegin(); it != moves_.rend(); ++it) {
    if (it->rotary == coordinate && it->start_time_s <= t_s) return &*it;
  }
  return nullptr;
}

Eigen::VectorXd VirtualMachine::errorsAt(const Eigen::VectorXd& q, const std::array<double, 3>& drive_um) const {
  Eigen::VectorXd e(static_cast<Eigen::Index>(curve_of_term_.size()));
  for (std::size_t t = 0; t < curve_of_term_.size(); ++t) {
    const int c = coordinate_of_term_[t];
    e(static_cast<Eigen::Index>(t)) = curve_of_term_[t] ? curve_of_term_[t]->value(c >= 0 ? q(c) : 0.0) : 0.0;
  }
  for (int a = 0; a < 3; ++a) e(positioning_term_[a]) += drive_um[a];
  return e;
}

void VirtualMachine::addVolumetric(const Eigen::VectorXd& q, std::array<double, 3>& drive_um) const {
  if (!config_.volumetric) return;
  const auto d = processing::volumetricCorrectionUm(model_, *config_.volumetric, q, positioning_term_);
  for (std::size_t a = 0; a < 3; ++a) drive_um[a] += d[a];
}

double VirtualMachine::compensationUm(int a, double position_mm, int direction) const {
  const auto& c = config_.compensation[static_cast<std::size_t>(a)];
  if (!c) return 0.0;
  return c->table.correctionUm(position_mm, direction > 0 ? processing::Direction::kUp : processing::Direction::kDown,
                               c->rules);
}

VirtualMachine::State VirtualMachine::stateAt(double t_s, bool with_errors) const {
  State s;
  s.q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model_.coordinates().size()));
  std::array<double, 3> drive_um{};
  for (int a = 0; a < 3; ++a) {
    const Move* move = lastMoveBefore(static_cast<Axis>(a), t_s);
    double position_mm = config_.axes[a].min_mm;  // where the constructor parks the axes
    int direction = 1;
    if (move && move->contour >= 0 && t_s < move->done_time_s) {
      // Inside a contouring move: the recorded servo output and drive error (lost motion included).
      const Contour& c = contours_[static_cast<std::size_t>(move->contour)];
      const double f = std::max(0.0, (t_s - c.start_s) / c.dt_s);
      const auto k = std::min(static_cast<std::size_t>(f), c.position_mm.size() - 2);
      const double w = std::min(1.0, f - static_cast<double>(k));
      s.q(coordinate_of_axis_[a]) = (1.0 - w) * c.position_mm[k][a] + w * c.position_mm[k + 1][a];
      drive_um[a] = (1.0 - w) * c.drive_um[k][a] + w * c.drive_um[k + 1][a];
      s.at_rest = false;
      continue;
    }
    if (move) {
      const double f =
          t_s >= move->done_time_s ? 1.0 : (t_s - move->start_time_s) / (move->done_time_s - move->start_time_s);
      position_mm = move->from_mm + f * (move->to_mm - move->from_mm);
      direction = move->direction;
      drive_um[a] = move->scatter_um + compensationUm(a, position_mm, direction);
      if (t_s < move->done_time_s) s.at_rest = false;
      if (move->contour < 0 && t_s >= move->done_time_s && t_s < move->done_time_s + settledAfterS()) {
        // Overshoot-free first-order approach of the last 0.5 % of the move.
        s.transient_um[a] = -0.005 * (move->to_mm - move->from_mm) * 1000.0 *
                            std::exp(-(t_s - move->done_time_s) / config_.settle_time_constant_s);
      }
    }
    drive_um[a] -= direction * config_.axes[a].backlash_um / 2.0;
    s.q(coordinate_of_axis_[a]) = position_mm;
  }
  for (std::size_t c = 0; c < rotary_commanded_deg_.size(); ++c) {
    const Move* move = lastRotaryMoveBefore(static_cast<int>(c), t_s);
    if (!move) continue;
    const double f =
        t_s >= move->done_time_s ? 1.0 : (t_s - move->start_time_s) / (move->done_time_s - move->start_time_s);
    if (f < 1.0) s.at_rest = false;
    s.q(static_cast<Eigen::Index>(c)) = move->from_mm + f * (move->to_mm - move->from_mm);
  }
  if (const Move* last = lastMoveStarted(t_s)) s.epoch = last->index + 1;
  addVolumetric(s.q, drive_um);
  s.drive_um = drive_um;
  if (with_errors) {
    s.errors = errorsAt(s.q, drive_um);
    for (int a = 0; a < 3; ++a) s.errors(positioning_term_[a]) += s.transient_um[a];
  }
  return s;
}

const VirtualMachine::RestPoint& VirtualMachine::restPoint(const State& s, const ToolOffset& offset_mm,
                                                           bool scaled) const {
  if (!rest_points_.empty() && rest_points_.front().epoch != s.epoch) rest_points_.clear();
  for (const auto& r : rest_points_) {
    if (r.offset == offset_mm && r.scaled == scaled) return r;
  }
  RestPoint r;
  r.epoch = s.epoch;
  r.offset = offset_mm;
  r.scaled = scaled;
  Eigen::VectorXd q = s.q;
  if (scaled) {
    const double scale = 1.0 + config_.expansion_per_k * (config_.material_temp_c - 20.0);
    for (int a = 0; a < 3; ++a) q(coordinate_of_axis_[a]) *= scale;
  }
  const Eigen::Vector3d p = toolPoint(offset_mm);
  const Eigen::VectorXd rest_errors = errorsAt(s.q, s.drive_um);  // without the settling transients
  r.actual_mm = model_.actualPoint(q, rest_errors, p);
  r.ideal_mm = model_.actualPoint(q, Eigen::VectorXd::Zero(rest_errors.size()), p);
  const Eigen::Matrix3Xd jac = model_.jacobian(q, p);  // E = P_ideal - P: dP/de = -J
  for (int a = 0; a < 3; ++a) r.per_positioning_um[static_cast<std::size_t>(a)] = -jac.col(positioning_term_[a]);
  rest_points_.push_back(r);
  return rest_points_.back();
}

Eigen::Vector3d VirtualMachine::transientUm(const RestPoint& r, const State& s) const {
  Eigen::Vector3d d = Eigen::Vector3d::Zero();
  for (std::size_t a = 0; a < 3; ++a) d += r.per_positioning_um[a] * s.transient_um[a];
  return d;
}

Eigen::Vector3d VirtualMachine::toolPoint(const ToolOffset& offset_mm) const {
  return model_.toolPoint() + Eigen::Vector3d(offset_mm[0], offset_mm[1], offset_mm[2]);
}

Eigen::Vector3d VirtualMachine::pointErrorUm(const ToolOffset& offset_mm, double t_s) const {
  std::lock_guard lock(mutex_);
  State s = stateAt(t_s, false);
  if (s.at_rest) {
    const RestPoint& r = restPoint(s, offset_mm, false);
    return (r.actual_mm - r.ideal_mm) * 1000.0 + transientUm(r, s) + thermalDriftUm(t_s);
  }
  s = stateAt(t_s);
  const Eigen::Vector3d p = toolPoint(offset_mm);
  return (model_.actualPoint(s.q, s.errors, p) - model_.actualPoint(s.q, Eigen::VectorXd::Zero(s.errors.size()), p)) *
             1000.0 +
         thermalDriftUm(t_s);
}

Eigen::Vector3d VirtualMachine::thermalDriftUm(double t_s) const {
  return thermal_ ? thermal_->driftUm(t_s) : Eigen::Vector3d::Zero();
}

Eigen::Vector3d VirtualMachine::rotationErrorUrad(double t_s) const {
  State s;
  {
    std::lock_guard lock(mutex_);
    s = stateAt(t_s);
  }
  return model_.orientationErrorUrad(s.q, s.errors);
}

double VirtualMachine::actualPositionMm(Axis measured, const ToolOffset& offset_mm, double t_s) const {
  return actualPointMm(offset_mm, t_s)(static_cast<int>(measured));
}

Eigen::Vector3d VirtualMachine::actualPointMm(const ToolOffset& offset_mm, double t_s) const {
  std::lock_guard lock(mutex_);
  State s = stateAt(t_s, false);
  if (s.at_rest) {
    const RestPoint& r = restPoint(s, offset_mm, true);
    return r.actual_mm + (transientUm(r, s) + thermalDriftUm(t_s)) / 1000.0;
  }
  s = stateAt(t_s);
  const double scale = 1.0 + config_.expansion_per_k * (config_.material_temp_c - 20.0);
  for (int a = 0; a < 3; ++a) s.q(coordinate_of_axis_[a]) *= scale;
  return model_.actualPoint(s.q, s.errors, toolPoint(offset_mm)) + thermalDriftUm(t_s) / 1000.0;
}

double VirtualMachine::staticErrorUm(Axis moving, const ToolOffset& offset_mm, double position_mm, int direction,
                                     int component) const {
  const Axis measured = moving;
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model_.coordinates().size()));
  std::array<double, 3> drive_um{};
  {
    std::lock_guard lock(mutex_);
    for (std::size_t c = 0; c < rotary_commanded_deg_.size(); ++c)
      q(static_cast<Eigen::Index>(c)) = rotary_commanded_deg_[c];
    for (int a = 0; a < 3; ++a) {
      q(coordinate_of_axis_[a]) = commanded_[a];
      drive_um[a] = -last_direction_[a] * config_.axes[a].backlash_um / 2.0 +  // the other axes' lost motion
                    (moved_[a] ? compensationUm(a, commanded_[a], last_direction_[a]) : 0.0);
    }
  }
  const int ai = static_cast<int>(measured);
  q(coordinate_of_axis_[ai]) = position_mm;
  drive_um[ai] = -direction * config_.axes[ai].backlash_um / 2.0 + compensationUm(ai, position_mm, direction);
  addVolumetric(q, drive_um);
  const Eigen::VectorXd e = errorsAt(q, drive_um);
  const Eigen::Vector3d p = toolPoint(offset_mm);
  return (model_.actualPoint(q, e, p) -
          model_.actualPoint(q, Eigen::VectorXd::Zero(e.size()), p))(component < 0 ? ai : component) *
         1000.0;
}

}  // namespace mtcal::mocks
