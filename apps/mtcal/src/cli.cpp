#include "mtcal/app/cli.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <string>

#include "commands.h"
#include "mtcal/error.h"
#include "mtcal/services/logging.h"

namespace mtcal::app {

void CliContext::on(CLI::App* command, std::function<int()> chosen, OnSignal on_signal_chosen) {
  command->callback([this, chosen = std::move(chosen), on_signal_chosen] {
    action = chosen;
    on_signal = on_signal_chosen;
  });
}

bool jsonPrinted(const Globals& g, const nlohmann::json& document) {
  if (g.json) *g.out << document.dump() << "\n";
  return g.json;
}

void addCsvOptions(CLI::App* command, CsvOptions& options) {
  command->add_option("--delimiter", options.delimiter,
                      "the separator: , ; tab | space (default: detected from the header and first rows)");
  command->add_option("--decimal", options.decimal, "the decimal mark: . or , (default: detected)");
  command->add_option("--columns", options.columns,
                      "the file's column for a name mtcal reads, e.g. target_mm=Position,deviation_um=Error");
}

// strtod also reads hex ("0x1p3"): refused.
std::optional<double> decimalNumber(const std::string& text) {
  if (text.empty() || text.find_first_of("xX") != std::string::npos) return std::nullopt;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);  // beyond a double's range: +-infinity, not "no number"
  if (end != text.c_str() + text.size()) return std::nullopt;
  return value;
}

CLI::Option* addXyzOption(CLI::App* command, const std::string& name, std::string& text, const std::string& help) {
  return command->add_option(name, text, help)->type_name(kXyzTypeName);
}

std::array<double, 3> xyzOption(const std::string& option, const std::string& text) {
  std::vector<std::string> parts{""};
  for (const char ch : text) {
    if (ch == ',') {
      parts.emplace_back();
    } else {
      parts.back().push_back(ch);
    }
  }
  if (parts.size() != 3) {
    throw InputError(fmt::format("{} takes x,y,z in mm (three numbers), got {} in '{}'", option, parts.size(), text));
  }
  std::array<double, 3> xyz{};
  for (std::size_t i = 0; i < 3; ++i) {
    const auto value = decimalNumber(parts[i]);
    if (!value || !std::isfinite(*value)) {
      throw InputError(fmt::format("{} takes x,y,z in mm, got '{}': its {} '{}' is not {}", option, text, "xyz"[i],
                                   parts[i], value ? "a finite number" : "a number"));
    }
    xyz[i] = *value;
  }
  return xyz;
}

namespace {

/// A number validator: the text parsed as a number, then `why_not` of it; empty: accepted.
template <class WhyNot>
CLI::Validator numberValidator(WhyNot why_not, std::string description, std::string name) {
  return CLI::Validator(
      [why_not](std::string& text) -> std::string {
        const auto value = decimalNumber(text);
        return value ? why_not(*value, text) : "must be a number, got '" + text + "'";
      },
      std::move(description), std::move(name));
}

/// CLI11 reads "" as 0 for a number: every option and argument of a number type refuses it
/// ("mtcal show ''" would show run 0).
void refuseEmptyNumbers(CLI::App& command) {
  for (CLI::Option* option : command.get_options()) {
    const auto type = option->get_type_name();
    const bool number = type.rfind("INT", 0) == 0 || type.rfind("UINT", 0) == 0 || type.rfind("FLOAT", 0) == 0;
    if (!number) continue;
    option->check(CLI::Validator(
        [](std::string& text) { return text.empty() ? std::string("a number is needed, got ''") : std::string(); }, "",
        "number given"));
  }
  for (CLI::App* sub : command.get_subcommands({})) refuseEmptyNumbers(*sub);
}

}  // namespace

CLI::Validator notEmpty(const std::string& what, const std::string& name) {
  return CLI::Validator(
      [what](std::string& text) { return text.empty() ? what + " is needed, got ''" : std::string(); }, name, "value");
}

CLI::Validator positive() {
  return numberValidator(
      [](double value, const std::string& text) {
        if (!std::isfinite(value)) return "must be a finite number > 0, got " + text;
        return value > 0.0 ? std::string() : "must be > 0, got " + text;
      },
      "> 0", "positive");
}

CLI::Validator between(double least, double greatest) {
  const std::string range = fmt::format("{} to {}", least, greatest);
  return numberValidator(
      [least, greatest, range](double value, const std::string& text) {  // a NaN fails both comparisons
        return value >= least && value <= greatest ? std::string() : "must be from " + range + ", got " + text;
      },
      range, "between");
}

CLI::Validator wholeBetween(long long least, long long greatest) {
  const std::string range = fmt::format("from {} to {}", least, greatest);
  auto check = numberValidator(
      [least, greatest, range](double value, const std::string& text) {
        if (!(value >= static_cast<double>(least) && value <= static_cast<double>(greatest)))  // a NaN too
          return "must be " + range + ", got " + text;
        return value == std::floor(value) ? std::string() : "must be a whole number, got " + text;
      },
      range, "whole number between");
  // A whole number written as 3.0 or 1e1 is that number: given on as the integer CLI11 reads.
  return CLI::Validator(
      [check, least, greatest, range](std::string& text) {
        // Digits alone are read as an integer: a double rounds those beyond 2^53 to a neighbour.
        const bool signed_text = !text.empty() && (text[0] == '-' || text[0] == '+');
        if (text.size() > (signed_text ? 1u : 0u) &&
            text.find_first_not_of("0123456789", signed_text ? 1 : 0) == std::string::npos) {
          long long value = 0;
          const auto* first = text.data() + (text[0] == '+' ? 1 : 0);
          const auto [end, error] = std::from_chars(first, text.data() + text.size(), value);
          if (error != std::errc() || end != text.data() + text.size() || value < least || value > greatest)
            return "must be " + range + ", got " + text;
          text = std::to_string(value);
          return std::string();
        }
        std::string why = check(text);
        // Written otherwise (3.0, 1e1), a number from 2^53 on may be a neighbour of the one meant.
        if (why.empty() && std::abs(*decimalNumber(text)) >= 0x1p53) why = "must be " + range + ", got " + text;
        if (why.empty()) text = std::to_string(static_cast<long long>(*decimalNumber(text)));
        return why;
      },
      range, "whole number between");
}

void addSimulationOptions(CLI::App* command, CliContext& c, const std::string& machine_help) {
  command
      ->add_option("--seed", c.sim.seed,
                   "seed of the simulated machine and instruments (with --machine-config: replaces the file's)")
      ->transform(wholeBetween(0, std::numeric_limits<long long>::max()));
  command->add_option("--time-scale", c.sim.time_scale, "simulated seconds per wall-clock second, at most")
      ->capture_default_str()
      ->check(positive());
  if (!machine_help.empty()) command->add_option("--machine-config", c.sim.machine_file, machine_help);
}

namespace {

/// Every subcommand's help ends with the options that go anywhere on the line.
void addGlobalFooter(CLI::App* app, const std::string& footer) {
  for (auto* sub : app->get_subcommands({})) {
    sub->footer(footer);
    addGlobalFooter(sub, footer);
  }
}

/// The names of a command's commands ("linear, ballbar, ..." of `run`), for a message.
std::string commandNames(const CLI::App& command) {
  std::vector<std::string> names;
  for (const auto* sub : command.get_subcommands({})) names.push_back(sub->get_name());
  return fmt::format("{}", fmt::join(names, ", "));
}

/// `mtcal help [COMMAND...]`: the help of the program or of a command; with `json`, as the one
/// document {"schema_version": 1, "help": TEXT}.
int printHelp(CLI::App& app, const std::vector<std::string>& words, std::ostream& out, bool json) {
  CLI::App* command = &app;
  std::string path = "mtcal";
  for (const auto& word : words) {
    CLI::App* sub = nullptr;
    try {
      sub = command->get_subcommand(word);
    } catch (const CLI::OptionNotFound&) {
    }
    if (!sub || sub->get_name() == "help") {
      const auto names = commandNames(*command);
      throw InputError(names.empty()
                           ? fmt::format("help: {} has no subcommands ('{}' is not one)", path, word)
                           : fmt::format("help: '{}' is not a command of {} (commands: {})", word, path, names));
    }
    command = sub;
    path += " " + word;
  }
  // The program's own help from its formatter: app.help() would show the selected `help`.
  const std::string text = command == &app ? app.get_formatter()->make_help(&app, "mtcal", CLI::AppFormatMode::Normal)
                                           : command->help(path.substr(0, path.rfind(' ')));
  if (json)
    out << nlohmann::json{{"schema_version", 1}, {"help", text}}.dump() << "\n";
  else
    out << text;
  return 0;
}

}  // namespace

int runCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err, const std::atomic<bool>* stop,
           std::istream* in, std::atomic<bool>* stop_awaited) {
  CLI::App app{"mtcal: open calibration of machine tools (laser interferometer, ballbar, probes, laser tracker)",
               "mtcal"};
  CliContext c;
  c.app = &app;
  c.g.out = &out;
  c.g.err = &err;
  c.g.in = in;
  c.g.stop = stop;
  c.g.terminal = &err == &std::cerr && isatty(STDERR_FILENO);

  app.set_version_flag("--version", std::string("mtcal ") + kVersion);
  app.require_subcommand(1);
  app.fallthrough();
  app.add_option("--db", c.g.db, "the store: an SQLite file (or the plant archive's address: read only)")
      ->capture_default_str();
  app.add_flag("--json", c.g.json, "print one JSON document on stdout");
  app.add_option("--operator", c.g.operator_name, "who measures: recorded with every run (default: $MTCAL_OPERATOR)")
      ->envname("MTCAL_OPERATOR");
  std::string log_level = "warn";
  app.add_option("--log-level", log_level, "diagnostics on stderr: off, error, warn, info, debug")
      ->capture_default_str()
      ->check(CLI::IsMember({"off", "error", "warn", "info", "debug"}));
  c.run = app.add_subcommand("run", "run a measurement plan")->require_subcommand(1);
  c.import = app.add_subcommand("import", "import measurements exported by other software")->require_subcommand(1);
  c.analyze = app.add_subcommand("analyze", "evaluate a stored run")->require_subcommand(1);

  for (const auto registerCommands :
       {registerArchiveCommands, registerLinearCommands, registerCircleCommands, registerEstCommands,
        registerGantryCommands, registerThermalCommands, registerModelCommands, registerGrindCommands,
        registerDiagnoseCommands, registerCompensateCommands, registerReportCommands, registerServeCommands,
        registerPlantCommands}) {
    registerCommands(c);
  }
  // --json asked on the line: a failure or a help while parsing comes before the flag is stored.
  const bool json_asked = std::any_of(args.begin(), args.end(), [](const std::string& a) {
    return a == "--json" || (a.rfind("--json=", 0) == 0 && a != "--json=false" && a != "--json=0" &&
                             a != "--json=off" && a != "--json=no");
  });
  std::vector<std::string> help_words;
  auto* help_cmd = app.add_subcommand("help", "help of mtcal or of a command: mtcal help run linear");
  help_cmd->add_option("COMMAND", help_words, "a command and its subcommands");
  c.on(help_cmd, [&] { return printHelp(app, help_words, out, json_asked); });
  addGlobalFooter(&app,
                  "\nGlobal options (anywhere on the line): --db FILE (default mtcal.sqlite), --json, --operator NAME, "
                  "--log-level LEVEL");

  // A failure: in words on stderr; with --json also as the one document on stdout.
  const auto fail = [&](int code, const std::string& prefix, const std::string& message) {
    err << prefix << message << "\n";
    if (c.g.json || json_asked)
      out << nlohmann::json{{"schema_version", 1}, {"error", message}, {"exit_code", code}}.dump() << "\n";
    return code;
  };
  std::vector<std::string> reversed(args.rbegin(), args.rend());
  refuseEmptyNumbers(app);
  try {
    app.parse(reversed);
  } catch (const CLI::ConversionError& e) {
    // CLI11 says "Could not convert: RUN = abc": in words, the id or number expected.
    std::string message = e.what();
    const auto colon = message.find(": "), equals = message.find(" = ");
    if (colon != std::string::npos && equals != std::string::npos && equals > colon) {
      const std::string name = message.substr(colon + 2, equals - colon - 2), value = message.substr(equals + 3);
      const bool id = name == "RUN" || name == "MODEL" || name == "CAMPAIGN";
      // A number that is not whole ("--seed 2.5") is not said to be no number.
      const bool number = decimalNumber(value).has_value();
      message = fmt::format("{} '{}' is not {}", name, value,
                            id       ? "an id (a whole number, as mtcal runs or mtcal model list show)"
                            : number ? "a whole number"
                                     : "a number");
    }
    return fail(2, "mtcal: error: ", message + " (mtcal help COMMAND lists its options)");
  } catch (const CLI::ArgumentMismatch& e) {
    // CLI11 says "--against: 1 required TEXT:MODEL missing" or "--centre-mm: At least 3 required
    // but received 2": in words, the values it needs.
    static const std::regex missing(R"(^(\S+): (\d+) required (\w+)(?::(.+))? missing$)");
    static const std::regex count(R"(^(\S+): At (least|Most) (\d+) required but received (\d+)$)", std::regex::icase);
    std::string message = e.what();
    if (std::smatch m; std::regex_match(message, m, missing)) {
      const std::string type = m[3];
      std::string label = m[4];
      if (label.rfind(type + " ", 0) == 0) label.erase(0, type.size() + 1);   // "INT in [1 - 10]"
      if (label.size() > 2 && label.front() == '{' && label.back() == '}') {  // a set: {linear,circle}
        label = "one of " + label.substr(1, label.size() - 2);
        for (std::size_t at = label.find(','); at != std::string::npos; at = label.find(',', at + 2))
          label.replace(at, 1, ", ");
      }
      const int values = std::stoi(m[2]);
      const std::string kind = type == "FLOAT"                   ? (values > 1 ? "numbers" : "a number")
                               : type == "INT" || type == "UINT" ? (values > 1 ? "whole numbers" : "a whole number")
                                                                 : "";
      const bool named = !label.empty() && std::all_of(label.begin(), label.end(), [](char ch) {
        return std::isupper(static_cast<unsigned char>(ch)) || ch == '_';
      });
      const std::string what = named ? label : kind.empty() ? label : label.empty() ? kind : kind + " " + label;
      message = fmt::format("{} needs {}{}", m[1].str(), values > 1 ? fmt::format("{} values", values) : "a value",
                            what.empty() ? "" : " (" + what + ")");
    } else if (std::regex_match(message, m, count)) {
      const bool least = std::tolower(static_cast<unsigned char>(m[2].str().front())) == 'l';
      message = !least && m[3].str() == "1"
                    ? fmt::format("{} is given {} times: it takes one value", m[1].str(), m[4].str())
                    : fmt::format("{} {} {} values, not {}", m[1].str(), least ? "needs" : "takes at most", m[3].str(),
                                  m[4].str());
    }
    return fail(2, "mtcal: error: ", message + " (mtcal help COMMAND lists its options)");
  } catch (const CLI::ExtrasError&) {
    // CLI11 lists them last first: in the order given; numbers after an x,y,z option's first value
    // (given as --option X or --option=X, without commas), with the commas they need.
    const auto extras = app.remaining(true);
    const auto xyzOptionNamed = [&](const std::string& name) {
      for (const CLI::App* command = &app; command;) {
        if (const auto* o = command->get_option_no_throw(name); o && o->get_type_name() == kXyzTypeName) return true;
        const auto under = command->get_subcommands();
        command = under.empty() ? nullptr : under.front();
      }
      return false;
    };
    const bool numbers = !extras.empty() && std::all_of(extras.begin(), extras.end(), [](const std::string& a) {
      return decimalNumber(a).has_value();
    });
    std::string commas;
    for (std::size_t i = 1; numbers && commas.empty() && i < args.size(); ++i) {
      if (args[i] != extras.front()) continue;
      const auto equals = args[i - 1].find('=');
      std::string option, value;
      if (args[i - 1].rfind("--", 0) == 0 && equals != std::string::npos) {
        option = args[i - 1].substr(0, equals);
        value = args[i - 1].substr(equals + 1);
      } else if (i >= 2) {
        option = args[i - 2];
        value = args[i - 1];
      }
      if (option.empty() || value.find(',') != std::string::npos || !decimalNumber(value) || !xyzOptionNamed(option))
        continue;
      const std::vector<std::string> given = {value, extras.front(), extras.size() > 1 ? extras[1] : "Z"};
      commas = fmt::format("{} takes x,y,z with commas: {} {}; ", option, option, fmt::join(given, ","));
    }
    return fail(
        2, "mtcal: error: ",
        fmt::format("{} not expected: {} ({}mtcal help COMMAND lists its options)",
                    extras.size() == 1 ? "this argument was" : "these arguments were", fmt::join(extras, " "), commas));
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) {
      const bool version = e.get_name() == "CallForVersion";
      if (json_asked)  // the one document --json promises
        out << nlohmann::json{{"schema_version", 1},
                              version ? nlohmann::json::object_t::value_type{"version", kVersion}
                                      : nlohmann::json::object_t::value_type{"help", app.help()}}
                   .dump()
            << "\n";
      else
        out << (version ? std::string("mtcal ") + kVersion + "\n" : app.help());
      return 0;
    }
    if (std::string(e.what()) == "A subcommand is required") {
      // The command given so far, and the word that is none of its commands (or none given).
      const CLI::App* command = &app;
      std::string path = "mtcal";
      for (auto under = command->get_subcommands(); !under.empty(); under = command->get_subcommands()) {
        command = under.front();
        path += " " + command->get_name();
      }
      const auto extras = app.remaining(true);
      const auto word =
          std::find_if(extras.begin(), extras.end(), [](const std::string& a) { return a.rfind('-', 0) != 0; });
      return fail(2, "mtcal: error: ",
                  fmt::format("{} (commands: {}; {} --help says what each does)",
                              word != extras.end() ? fmt::format("'{}' is not a command of {}", *word, path)
                                                   : path + " needs a command",
                              commandNames(*command), path));
    }
    return fail(2, "mtcal: error: ",
                std::string(e.what()) + " (mtcal help lists the commands, mtcal help COMMAND its options)");
  }

  services::logToStderr(log_level);
  c.g.quiet = log_level == "off";
  if (stop_awaited) *stop_awaited = c.on_signal == OnSignal::kStopAndWait;
  try {
    if (c.action) return c.action();
  } catch (const InputError& e) {
    return fail(2, "mtcal: error: ", e.what());
  } catch (const Error& e) {
    return fail(1, "mtcal: error: ", e.what());
  } catch (const std::exception& e) {
    return fail(1, "mtcal: internal error: ", e.what());
  }
  return fail(2, "mtcal: ", "no command given (mtcal help)");
}

}  // namespace mtcal::app
