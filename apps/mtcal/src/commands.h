#pragma once
// The commands of the mtcal command line, one registration function per subject. Each adds
// its subcommands and options to the parser and says what runs when one is chosen; the
// command functions parse nothing, call services and render what they return (text or one
// JSON document on stdout; progress and messages on stderr).

#include <CLI/CLI.hpp>
#include <array>
#include <atomic>
#include <functional>
#include <istream>
#include <nlohmann/json.hpp>
#include <optional>
#include <ostream>
#include <string>

#include "mtcal/services/circle.h"
#include "mtcal/services/est.h"
#include "mtcal/services/gantry.h"
#include "mtcal/services/linear.h"
#include "mtcal/services/thermal.h"
#include "mtcal/services/version.h"
#include "mtcal/services/workshop.h"

namespace mtcal::app {

struct Globals {
  std::string db = "mtcal.sqlite";
  std::string operator_name;  ///< recorded with every run (--operator or MTCAL_OPERATOR)
  bool json = false;
  std::ostream* out = nullptr;
  std::ostream* err = nullptr;
  std::istream* in = nullptr;  ///< the operator's answers (real-machine prompts); none: no prompts possible
  const std::atomic<bool>* stop = nullptr;
  bool terminal = false;  ///< stderr is a terminal: draw the progress bar in place
  bool quiet = false;     ///< --log-level off: no progress either
};

using services::kVersion;
using services::readTextFile;
using services::SimulationOptions;

/// What a first Ctrl-C, SIGTERM or SIGHUP does to a command: ends it at once (files are written
/// aside and renamed, SQLite rolls back), or asks it to stop and waits (a run stops after its
/// current target, the dashboard closes, a backup finishes its SQLite step); a second ends it at
/// once.
enum class OnSignal { kEndAtOnce, kStopAndWait };

/// The parser being built, what parsing fills in and the command chosen.
struct CliContext {
  CLI::App* app = nullptr;
  CLI::App* run = nullptr;      ///< `mtcal run KIND`
  CLI::App* import = nullptr;   ///< `mtcal import KIND`
  CLI::App* analyze = nullptr;  ///< `mtcal analyze KIND`
  Globals g;
  SimulationOptions sim;                      ///< the simulated machine of mock:// instruments
  std::function<int()> action;                ///< the chosen command (set when it is parsed)
  OnSignal on_signal = OnSignal::kEndAtOnce;  ///< the chosen command's
  /// `command`, when chosen, runs `action` after parsing, a signal doing `on_signal`.
  void on(CLI::App* command, std::function<int()> chosen, OnSignal on_signal = OnSignal::kEndAtOnce);
};

/// With --json, prints the document on one line of stdout and returns true (the text
/// rendering is skipped); without, returns false.
bool jsonPrinted(const Globals& g, const nlohmann::json& document);

/// A value that is not empty: "a file name is needed, got ''" for `what` "a file name" (an
/// empty -o would otherwise mean stdout, as if it were not given).
CLI::Validator notEmpty(const std::string& what, const std::string& name);

/// A number > 0, refused in words ("must be > 0, got -5") where CLI11's own check prints the
/// largest double.
CLI::Validator positive();
/// A finite number from `least` to `greatest` (CLI::Range lets a NaN through).
CLI::Validator between(double least, double greatest);
/// A whole number from `least` to `greatest` ("must be a whole number, got 2.5"; 3.0 and 1e1 are
/// given on as 3 and 10: use with `transform`, which may change the text; CLI::Range says
/// "not in range" of a fraction or a word).
CLI::Validator wholeBetween(long long least, long long greatest);

/// An option's x,y,z in mm: three decimal numbers separated by commas. @throws InputError naming
/// the option and the value that is not a number ("--centre-mm takes x,y,z in mm, got '1,,3':
/// its y '' is not a number")
std::array<double, 3> xyzOption(const std::string& option, const std::string& text);
/// Adds an option of x,y,z in mm, read later by xyzOption: its type is kXyzTypeName, by which a
/// refusal of values given with spaces knows to say the commas.
CLI::Option* addXyzOption(CLI::App* command, const std::string& name, std::string& text, const std::string& help);
inline constexpr const char* kXyzTypeName = "X,Y,Z";
/// An option's number: a decimal number, the whole text (not hex: "0x10"); none if it is not one.
std::optional<double> decimalNumber(const std::string& text);

/// How an imported CSV file is written, as given on the command line (empty: detected).
struct CsvOptions {
  std::string delimiter, decimal;
  std::vector<std::string> columns;
  acquisition::CsvDialect dialect() const { return acquisition::CsvDialect::fromOptions(delimiter, decimal, columns); }
};
/// --delimiter, --decimal and --columns of an import.
void addCsvOptions(CLI::App* command, CsvOptions& options);

/// --seed, --time-scale and --machine-config (`machine_help`: what the file describes).
void addSimulationOptions(CLI::App* command, CliContext& c, const std::string& machine_help);

/// How a run of each kind ended (its run command and `mtcal resume` print it). @return the exit code
int printLinearRun(const Globals& g, const services::LinearRunResult& r, const std::string& plan_name);
int printCircleRun(const Globals& g, const services::CircleRunResult& r);
int printEstRun(const Globals& g, const services::EstRunResult& r);
int printGantryRun(const Globals& g, const services::GantryRunResult& r);
int printThermalRun(const Globals& g, const services::ThermalRunResult& r);

void registerArchiveCommands(CliContext& c);  ///< runs, show, resume, delete, rename, note, backup, check, devices
void registerLinearCommands(
    CliContext& c);  ///< demo, run linear, import linear, analyze iso230-2, air-index, plan gcode
void registerCircleCommands(CliContext& c);      ///< run ballbar, import circle, analyze iso230-4, analyze ballbar
void registerEstCommands(CliContext& c);         ///< est, run est, analyze est
void registerGantryCommands(CliContext& c);      ///< run gantry, gantry run/evaluate/export, analyze gantry
void registerThermalCommands(CliContext& c);     ///< run thermal, import thermal, thermal export/fit
void registerModelCommands(CliContext& c);       ///< model import/identify/list/predict/key-errors/bands/validate
void registerGrindCommands(CliContext& c);       ///< grind compensate/identify
void registerDiagnoseCommands(CliContext& c);    ///< diagnose
void registerCompensateCommands(CliContext& c);  ///< compensate
void registerReportCommands(CliContext& c);      ///< report
void registerServeCommands(CliContext& c);       ///< serve
void registerPlantCommands(CliContext& c);       ///< archive push/runs/pull

}  // namespace mtcal::app
