#include "mtcal/services/workshop.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "mtcal/acquisition/csv.h"
#include "mtcal/error.h"
#include "mtcal/services/compensate.h"

namespace mtcal::services {

Simulation::Simulation(mocks::VirtualMachineConfig machine, mocks::InterferometerEmulatorConfig interferometer,
                       double time_scale, mocks::WorldClock::Mode mode)
    : world(std::move(machine), std::move(interferometer), time_scale, mode), controller(world.machine) {
  drivers::registerBuiltInDrivers(registry);
  mocks::registerMockDrivers(registry, world);
}

void WorldRunClock::advanceTo(double device_time_s) {
  // Device time stamps are rounded (to the microsecond at the coarsest): a microsecond more
  // brings the reading stamped `device_time_s` whatever its rounding.
  clock_.advanceTo(device_time_s + 1e-6);
}

std::optional<double> WorldRunClock::nowS() const {
  if (!clock_.lockStep()) return std::nullopt;
  return clock_.nowS();
}

void Simulation::setUpFor(const acquisition::LinearPlan& plan) {
  world.interferometer->mount(mocks::parseAxis(plan.axis), acquisition::measuredComponent(plan),
                              plan.reflector_offset_mm);
}

void Simulation::setUpFor(const acquisition::CirclePlan& plan) {
  world.ballbar->fitLength(static_cast<int>(std::lround(plan.radius_mm)));
  world.ballbar->placeInCalibrator();
}

std::string readTextFile(const std::string& path) {
  auto in = acquisition::openInputFile(path);  // a folder named as one
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void writeTextFile(const std::string& path, const std::string& text) { writeTextFiles({{path, text}}); }

void writeTextFiles(const std::vector<std::pair<std::string, std::string>>& path_and_text) {
  // What would fail a rename, found before anything is written: a folder, one file named twice.
  std::vector<std::filesystem::path> targets;
  for (const auto& [path, text] : path_and_text) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) throw InputError(path + ": a folder, not a file to write");
    auto target = std::filesystem::weakly_canonical(path, ec);
    if (ec) target = std::filesystem::absolute(path, ec);
    for (std::size_t k = 0; k < targets.size(); ++k) {
      if (targets[k] == target)
        throw InputError(fmt::format("{} and {} are one file: give each its own", path_and_text[k].first, path));
    }
    targets.push_back(target);
  }
  std::vector<std::string> parts;
  const auto refuse = [&](const std::string& path, const std::string& why, std::size_t first_part) {
    for (std::size_t k = first_part; k < parts.size(); ++k) std::remove(parts[k].c_str());
    throw InputError(path + ": " + why);
  };
  for (const auto& [path, text] : path_and_text) {
    const std::string part = path + ".part";
    std::ofstream out(part, std::ios::binary | std::ios::trunc);
    if (!out) refuse(path, fmt::format("cannot write ({})", std::strerror(errno)), 0);
    parts.push_back(part);
    if (!(out << text) || !out.flush()) {
      out.close();
      refuse(path, "writing failed (disk full?)", 0);
    }
  }
  for (std::size_t k = 0; k < parts.size(); ++k) {
    const std::string& path = path_and_text[k].first;
    if (std::rename(parts[k].c_str(), path.c_str()) != 0)
      refuse(path, fmt::format("cannot write ({})", std::strerror(errno)), k);
  }
}

void requireInTravel(const mocks::VirtualMachineConfig& machine, mocks::Axis axis, double position_mm,
                     const std::string& what) {
  const auto& travel = machine.axes[static_cast<std::size_t>(axis)];
  if (!travel.reaches(position_mm)) {
    // A position far beyond in a few digits (a radius of 1e300 mm is not 300 digits long).
    const auto at = std::abs(position_mm) < 1e9 ? fmt::format("{:.3f}", position_mm) : fmt::format("{:g}", position_mm);
    throw InputError(fmt::format("{} needs {} at {} mm, outside the machine's travel [{}, {}] mm", what,
                                 mocks::axisName(axis), at, travel.min_mm, travel.max_mm));
  }
}

namespace {

/// The tables a machine file's controller runs: its key "compensation", a list of {"axis",
/// "file", "controller"} with files relative to the machine file's folder. The key is taken
/// out: tables are stored with the runs, not with the machine. @throws InputError naming the key
std::vector<ControllerTable> takeTables(nlohmann::json& machine, const std::string& path) {
  std::vector<ControllerTable> tables;
  if (!machine.is_object() || !machine.contains("compensation")) return tables;
  const auto list = machine["compensation"];
  machine.erase("compensation");
  const std::string what = fmt::format("{}: key 'compensation'", path);
  if (!list.is_array()) throw InputError(what + ": a list of {\"axis\", \"file\", \"controller\"}");
  for (std::size_t i = 0; i < list.size(); ++i) {
    const auto& t = list[i];
    ControllerTable table;
    for (auto [key, field] :
         {std::pair{"axis", &table.axis}, {"file", &table.path}, {"controller", &table.controller}}) {
      if (!t.is_object() || !t.contains(key) || !t[key].is_string())
        throw InputError(fmt::format("{}: entry {}: '{}' is missing or not text", what, i + 1, key));
      *field = t[key].get<std::string>();
    }
    for (const auto& [key, value] : t.items()) {
      if (key != "axis" && key != "file" && key != "controller")
        throw InputError(fmt::format("{}: entry {}: unknown key '{}' (axis, file, controller)", what, i + 1, key));
    }
    const std::filesystem::path file(table.path);
    if (file.is_relative()) table.path = (std::filesystem::path(path).parent_path() / file).lexically_normal().string();
    tables.push_back(std::move(table));
  }
  return tables;
}

/// The machine of the options, its controller without compensation tables; `file_tables`: the
/// tables its machine file names.
SimulatedMachine machineWithoutTables(const SimulationOptions& options, std::vector<ControllerTable>& file_tables) {
  SimulatedMachine m;
  if (options.machine_file.empty()) {
    m.config = mocks::VirtualMachineConfig::demo(options.seed.value_or(1));
    return m;
  }
  auto j = readJsonFile(options.machine_file);
  file_tables = takeTables(j, options.machine_file);
  if (options.seed && j.is_object() && !(j.contains("seed") && j["seed"] == *options.seed)) {
    j["seed"] = *options.seed;
    m.seed_replaced = true;
  }
  m.config = mocks::VirtualMachineConfig::fromJson(j, options.machine_file);
  // Stored whole: a kinematics file named beside the machine file is copied in, so the run is
  // resumed (or the machine rebuilt) wherever, and whenever, the archive is opened.
  if (j.is_object() && j.contains("kinematics") && j["kinematics"].is_string())
    j["kinematics"] = nlohmann::json::parse(m.config.kinematics_json);
  m.file_json = j.dump();
  return m;
}

}  // namespace

SimulatedMachine simulatedMachine(const SimulationOptions& options) {
  std::vector<ControllerTable> tables;
  SimulatedMachine m = machineWithoutTables(options, tables);
  // A table given on the command line replaces the machine file's for its axis; two given for one axis are one too
  // many.
  const auto sameAxis = [](const ControllerTable& a, const ControllerTable& b) {
    return std::ranges::equal(a.axis, b.axis, [](char x, char y) { return std::toupper(x) == std::toupper(y); });
  };
  for (auto t = options.compensation.begin(); t != options.compensation.end(); ++t) {
    const auto again = std::find_if(std::next(t), options.compensation.end(),
                                    [&](const ControllerTable& other) { return sameAxis(*t, other); });
    if (again != options.compensation.end())
      throw InputError(
          fmt::format("--compensation: two tables for axis {} ({} and {})", t->axis, t->path, again->path));
  }
  for (const auto& t : options.compensation) {
    std::erase_if(tables, [&](const ControllerTable& f) { return sameAxis(f, t); });
    tables.push_back(t);
  }
  if (!tables.empty() && !options.records_tables) {
    throw InputError(fmt::format(
        "{}: names compensation tables (key 'compensation'), which only linear runs run and record so far: use a "
        "machine file without them",
        options.machine_file));
  }
  m.compensation_json = compensationRecord(tables);
  applyCompensation(m.compensation_json, m.config);
  return m;
}

std::string SimulatedMachine::name() const {
  return file_json.empty() || seed_replaced ? fmt::format("{} (seed {})", config.name, config.seed) : config.name;
}

std::string SimulatedMachine::description() const {
  if (!file_json.empty()) return nlohmann::json{{"simulation", nlohmann::json::parse(file_json)}}.dump();
  return nlohmann::json{{"simulation", {{"demo_seed", config.seed}}}}.dump();
}

storage::Id simulatedCampaign(storage::Store& store, const SimulatedMachine& machine,
                              const std::string& campaign_name) {
  return store.addCampaign(store.ensureMachine(machine.name(), "simulated machine", machine.description()),
                           campaign_name);
}

processing::MultibodyModel machineKinematics(const std::string& path) {
  const auto file = readJsonFile(path);
  if (file.contains("joints")) return processing::MultibodyModel::fromJson(file, path);
  return mocks::VirtualMachineConfig::fromJson(file, path).kinematics();
}

storage::Id realCampaign(storage::Store& store, const std::string& machine_name, const std::string& campaign_name) {
  return store.addCampaign(store.ensureMachine(machine_name, "real machine", "{}"), campaign_name);
}

mocks::InterferometerEmulatorConfig demoInterferometer() {
  mocks::InterferometerEmulatorConfig c;
  c.noise_um = 0.02;
  return c;
}

std::optional<mocks::VirtualMachineConfig> simulationFromDescription(const std::string& config_json) {
  const auto j = nlohmann::json::parse(config_json, nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("simulation")) return std::nullopt;
  const auto& sim = j["simulation"];
  if (sim.contains("demo_seed")) {
    if (!sim["demo_seed"].is_number_unsigned())
      throw InputError("stored machine description: 'demo_seed' must be a whole number >= 0");
    return mocks::VirtualMachineConfig::demo(sim["demo_seed"].get<std::uint64_t>());
  }
  return mocks::VirtualMachineConfig::fromJson(sim, "stored machine description");
}

std::string StoredRig::uriOf(const std::string& role) const {
  for (const auto& i : instruments) {
    if (i.role == role) return i.info.driver_uri;
  }
  throw InputError(fmt::format("run {} has no {} instrument stored: it cannot be resumed", run.id, role));
}

StoredRig storedRig(storage::Store& store, storage::Id run_id) {
  StoredRig rig;
  rig.run = store.run(run_id);
  if (rig.run.source != "acquired") {
    throw InputError(
        fmt::format("run {} was imported: there is nothing to resume (import the rest as another run)", run_id));
  }
  if (rig.run.status == storage::run_status::kCompleted)
    throw InputError(fmt::format(
        "run {} is already completed: there is nothing to resume (to measure again, run its plan as a new run)",
        run_id));
  rig.instruments = store.runInstruments(run_id);
  rig.simulation = simulationFromDescription(store.machineDescriptionOfRun(run_id));
  if (rig.simulation) applyCompensation(rig.run.compensation_json, *rig.simulation);  // what its controller ran
  return rig;
}

}  // namespace mtcal::services
