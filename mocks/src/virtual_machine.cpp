#include "mtcal/mocks/virtual_machine.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "mtcal/error.h"
#include "mtcal/mocks/random.h"

namespace mtcal::mocks {
namespace {

constexpr std::uint64_t kScatterStream = 1;
constexpr const char* kTranslationNames[3][3] = {
    {"EXX", "EYX", "EZX"}, {"EXY", "EYY", "EZY"}, {"EXZ", "EYZ", "EZZ"}};
constexpr const char* kRotationNames[3][3] = {
    {"EAX", "EBX", "ECX"}, {"EAY", "EBY", "ECY"}, {"EAZ", "EBZ", "ECZ"}};

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
  for (const auto& h : harmonics) v += h.amplitude * std::sin(2.0 * std::numbers::pi * pos_mm / h.period_mm + h.phase_rad);
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
  for (const auto& [key, value] : j.items()) {
    if (key == "name") {
      if (!value.is_string()) bad(source, key, "must be a string");
      c.name = value.get<std::string>();
    } else if (key == "seed") {
      if (!value.is_number_unsigned()) bad(source, key, "must be a non-negative integer");
      c.seed = value.get<std::uint64_t>();
    } else if (key == "axes") {
      if (!value.is_object()) bad(source, key, "must be an object keyed by X, Y, Z");
      for (const auto& [axis_name, a] : value.items()) {
        Axis axis;
        try {
          axis = parseAxis(axis_name);
        } catch (const InputError& e) {
          bad(source, "axes." + axis_name, e.what());
        }
        const int ai = static_cast<int>(axis);
        AxisModel& m = c.axes[ai];
        const std::string path = "axes." + axis_name + ".";
        for (const auto& [akey, avalue] : a.items()) {
          if (akey == "errors") {
            for (const auto& [ename, curve] : avalue.items()) {
              bool found = false;
              for (int k = 0; k < 3; ++k) {
                if (ename == kTranslationNames[ai][k]) {
                  m.translation_um[k] = curveFromJson(curve, source, path + "errors." + ename);
                  found = true;
                } else if (ename == kRotationNames[ai][k]) {
                  m.rotation_urad[k] = curveFromJson(curve, source, path + "errors." + ename);
                  found = true;
                }
              }
              if (!found) {
                bad(source, path + "errors." + ename,
                    std::string("not an error of axis ") + axisName(axis) + " (expected " + kTranslationNames[ai][0] +
                        ", " + kTranslationNames[ai][1] + ", " + kTranslationNames[ai][2] + ", " +
                        kRotationNames[ai][0] + ", " + kRotationNames[ai][1] + ", " + kRotationNames[ai][2] + ")");
              }
            }
          } else if (akey != "min_mm" && akey != "max_mm" && akey != "backlash_um" && akey != "positioning_sigma_um") {
            bad(source, path + akey, "unknown key (expected min_mm, max_mm, backlash_um, positioning_sigma_um, errors)");
          }
        }
        m.min_mm = number(a, "min_mm", m.min_mm, source, path);
        m.max_mm = number(a, "max_mm", m.max_mm, source, path);
        m.backlash_um = number(a, "backlash_um", 0.0, source, path);
        m.positioning_sigma_um = number(a, "positioning_sigma_um", 0.0, source, path);
        if (!(m.max_mm > m.min_mm)) bad(source, path + "max_mm", "must be greater than min_mm");
        if (m.positioning_sigma_um < 0.0) bad(source, path + "positioning_sigma_um", "must be >= 0");
      }
    } else if (key == "squareness") {
      c.squareness_c0y_urad = number(value, "EC0Y", 0.0, source, "squareness.");
      c.squareness_b0z_urad = number(value, "EB0Z", 0.0, source, "squareness.");
      c.squareness_a0z_urad = number(value, "EA0Z", 0.0, source, "squareness.");
    } else if (key != "settle_time_constant_s" && key != "feed_mm_per_min" && key != "expansion_per_k" &&
               key != "material_temp_c" && key != "air_temp_c" && key != "air_pressure_pa" && key != "humidity_pct") {
      bad(source, key, "unknown key");
    }
  }
  c.settle_time_constant_s = number(j, "settle_time_constant_s", c.settle_time_constant_s, source, "");
  c.feed_mm_per_min = number(j, "feed_mm_per_min", c.feed_mm_per_min, source, "");
  c.expansion_per_k = number(j, "expansion_per_k", c.expansion_per_k, source, "");
  c.material_temp_c = number(j, "material_temp_c", c.material_temp_c, source, "");
  c.air_temp_c = number(j, "air_temp_c", c.air_temp_c, source, "");
  c.air_pressure_pa = number(j, "air_pressure_pa", c.air_pressure_pa, source, "");
  c.humidity_pct = number(j, "humidity_pct", c.humidity_pct, source, "");
  if (!(c.feed_mm_per_min > 0.0)) bad(source, "feed_mm_per_min", "must be > 0");
  if (c.settle_time_constant_s < 0.0) bad(source, "settle_time_constant_s", "must be >= 0");
  return c;
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
  }
  auto& x = c.axes[0];
  // EXX: a slow scale error with a bow and a 180 mm undulation (um; poly in um/m^k).
  x.translation_um[0] = {{0.0, 9.0, -7.0}, {{1.2, 180.0, 0.4}}};
  x.translation_um[1] = {{0.0, -2.0, 6.0}, {}};    // EYX straightness
  x.translation_um[2] = {{0.0, 3.0, -4.0}, {}};    // EZX straightness
  x.rotation_urad[0] = {{0.0, 4.0}, {}};           // EAX roll
  x.rotation_urad[1] = {{0.0, 18.0, -8.0}, {}};    // EBX pitch
  x.rotation_urad[2] = {{1.0, -10.0, 14.0}, {}};   // ECX yaw
  c.axes[1].translation_um[1] = {{0.0, -6.0, 4.0}, {}};
  c.axes[2].translation_um[2] = {{0.0, 5.0, 3.0}, {}};
  c.squareness_c0y_urad = 12.0;
  c.squareness_b0z_urad = -8.0;
  c.squareness_a0z_urad = 5.0;
  c.material_temp_c = 20.6;
  c.air_temp_c = 20.4;
  c.air_pressure_pa = 100650.0;
  c.humidity_pct = 42.0;
  return c;
}

VirtualMachine::VirtualMachine(VirtualMachineConfig config, WorldClock& clock)
    : config_(std::move(config)), clock_(clock) {
  for (int a = 0; a < 3; ++a) commanded_[a] = config_.axes[a].min_mm;
}

double VirtualMachine::moveTo(Axis axis, double target_mm) {
  const auto& model = config_.axes[static_cast<int>(axis)];
  if (!(target_mm >= model.min_mm - 1e-9 && target_mm <= model.max_mm + 1e-9)) {
    throw InputError(std::string("move of ") + axisName(axis) + " to " + std::to_string(target_mm) +
                     " mm is outside the travel [" + std::to_string(model.min_mm) + ", " +
                     std::to_string(model.max_mm) + "]");
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
  m.scatter_um = model.positioning_sigma_um * normalFromKey(config_.seed, kScatterStream, m.index);
  m.start_time_s = clock_.nowS();
  m.done_time_s = m.start_time_s + std::abs(m.to_mm - m.from_mm) / (config_.feed_mm_per_min / 60.0);
  commanded_[ai] = target_mm;
  moves_.push_back(m);
  return m.done_time_s;
}

std::array<double, 3> VirtualMachine::commanded() const {
  std::lock_guard lock(mutex_);
  return commanded_;
}

std::uint64_t VirtualMachine::moveCount() const {
  std::lock_guard lock(mutex_);
  return moves_.size();
}

std::pair<std::uint64_t, double> VirtualMachine::moveEpoch(Axis axis, double t_s) const {
  std::lock_guard lock(mutex_);
  const Move* move = lastMoveBefore(axis, t_s);
  return move ? std::pair{move->index + 1, move->done_time_s} : std::pair{std::uint64_t{0}, 0.0};
}

const VirtualMachine::Move* VirtualMachine::lastMoveBefore(Axis axis, double t_s) const {
  for (auto it = moves_.rbegin(); it != moves_.rend(); ++it) {
    if (it->axis == axis && it->start_time_s <= t_s) return &*it;
  }
  return nullptr;
}

double VirtualMachine::nominalPosition(const Move* move, int axis_index, double t_s) const {
  if (!move) return config_.axes[axis_index].min_mm;  // where the constructor parks the axes
  if (t_s >= move->done_time_s) return move->to_mm;
  const double f = (t_s - move->start_time_s) / (move->done_time_s - move->start_time_s);
  return move->from_mm + f * (move->to_mm - move->from_mm);
}

double VirtualMachine::pointErrorUm(Axis measured, const std::array<double, 3>& offset_mm, double t_s) const {
  std::lock_guard lock(mutex_);
  const int ai = static_cast<int>(measured);
  const auto& model = config_.axes[ai];
  const Move* move = lastMoveBefore(measured, t_s);
  const double position_mm = nominalPosition(move, ai, t_s);
  double dynamic_um = 0.0;
  int direction = 1;
  double scatter_um = 0.0;
  if (move) {
    direction = move->direction;
    scatter_um = move->scatter_um;
    if (t_s >= move->done_time_s && t_s < move->done_time_s + settledAfterS()) {
      // Overshoot-free first-order approach of the last 0.5 % of the move.
      dynamic_um = -0.005 * (move->to_mm - move->from_mm) * 1000.0 *
                   std::exp(-(t_s - move->done_time_s) / config_.settle_time_constant_s);
    }
  }
  return geometricErrorUm(measured, offset_mm, position_mm) - direction * model.backlash_um / 2.0 + scatter_um +
         dynamic_um;
}

std::array<double, 3> VirtualMachine::pointDisplacementUm(Axis axis, const std::array<double, 3>& offset_mm,
                                                          double position_mm) const {
  const auto& model = config_.axes[static_cast<int>(axis)];
  // Small-angle rigid body: displacement of the offset point = translation + eps x r.
  std::array<double, 3> delta_um{};
  std::array<double, 3> eps_rad{};
  for (int k = 0; k < 3; ++k) {
    delta_um[k] = model.translation_um[k].value(position_mm);
    eps_rad[k] = model.rotation_urad[k].value(position_mm) * 1e-6;
  }
  const auto& r = offset_mm;
  return {delta_um[0] + (eps_rad[1] * r[2] - eps_rad[2] * r[1]) * 1000.0,
          delta_um[1] + (eps_rad[2] * r[0] - eps_rad[0] * r[2]) * 1000.0,
          delta_um[2] + (eps_rad[0] * r[1] - eps_rad[1] * r[0]) * 1000.0};
}

double VirtualMachine::geometricErrorUm(Axis measured, const std::array<double, 3>& offset_mm,
                                        double position_mm) const {
  return pointDisplacementUm(measured, offset_mm, position_mm)[static_cast<std::size_t>(measured)];
}

double VirtualMachine::errorComponentAt(Axis axis, int component, const std::array<double, 3>& offset_mm,
                                        double t_s) const {
  double position_mm;
  {
    std::lock_guard lock(mutex_);
    const int ai = static_cast<int>(axis);
    position_mm = nominalPosition(lastMoveBefore(axis, t_s), ai, t_s);
  }
  if (component < 3) return pointDisplacementUm(axis, offset_mm, position_mm)[static_cast<std::size_t>(component)];
  return config_.axes[static_cast<int>(axis)].rotation_urad[static_cast<std::size_t>(component - 3)].value(position_mm);
}

double VirtualMachine::staticErrorUm(Axis measured, const std::array<double, 3>& offset_mm, double position_mm,
                                     int direction) const {
  return geometricErrorUm(measured, offset_mm, position_mm) -
         direction * config_.axes[static_cast<int>(measured)].backlash_um / 2.0;
}

double VirtualMachine::actualPositionMm(Axis measured, const std::array<double, 3>& offset_mm, double t_s) const {
  double nominal_mm;
  {
    std::lock_guard lock(mutex_);
    const int ai = static_cast<int>(measured);
    nominal_mm = nominalPosition(lastMoveBefore(measured, t_s), ai, t_s);
  }
  const double scale = 1.0 + config_.expansion_per_k * (config_.material_temp_c - 20.0);
  return (nominal_mm + offset_mm[static_cast<int>(measured)]) * scale + pointErrorUm(measured, offset_mm, t_s) / 1000.0;
}

}  // namespace mtcal::mocks
