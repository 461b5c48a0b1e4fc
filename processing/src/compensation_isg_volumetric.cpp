// ISG (TwinCAT CNC, TF5280) volumetric compensation: the model's component and position errors
// in ISG's CSV, read back as the controller reads it, and the correction a controller with the
// machine's kinematics makes from them. Sources and what is not verified: docs/compensation.md.

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>
#include <sstream>

#include "compensation_text.h"
#include "mtcal/error.h"
#include "mtcal/processing/compensation.h"
#include "mtcal/processing/volumetric_compensation.h"

namespace mtcal::processing {
namespace {

constexpr double kMmPerUm = 1e-3, kRadPerUrad = 1e-6;
constexpr std::string_view kAxisLetters = "XYZABC";

bool isAxisLetter(char c) { return kAxisLetters.find(c) != std::string_view::npos; }
bool isRotary(char axis_letter) { return axis_letter >= 'A' && axis_letter <= 'C'; }
char upper(char c) { return static_cast<char>(std::toupper(static_cast<unsigned char>(c))); }
char lower(char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); }

/// A motion error's component letter is a rotation (A, B, C): its value is in rad in the file.
bool isAngle(const std::string& term) { return term.size() >= 2 && isRotary(term[1]); }

/// ISG's name of a term: component errors as ISO 230-1 writes them (EYX), position errors
/// without the leading E (EC0Y -> C0Y). @throws InputError for a name ISG has no column for
std::string isgName(const std::string& term, bool motion) {
  const bool ok = term.size() == (motion ? 3u : 4u) && term[0] == 'E' && isAxisLetter(term[1]) &&
                  isAxisLetter(term.back()) && (motion || term[2] == '0');
  if (!ok) throw InputError(fmt::format("the error term '{}' has no column in ISG's volumetric compensation", term));
  return motion ? term : term.substr(1);
}

std::vector<std::string> tokensOf(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> tokens;
  for (std::string t; in >> t;) tokens.push_back(t);
  return tokens;
}

/// The value of one axis' term at a position: linear between rows, held beyond the ends.
double interpolate(const std::vector<double>& position, const std::vector<double>& value, double at) {
  if (at <= position.front()) return value.front();
  if (at >= position.back()) return value.back();
  const auto k = static_cast<std::size_t>(std::upper_bound(position.begin(), position.end(), at) - position.begin());
  const double w = (at - position[k - 1]) / (position[k] - position[k - 1]);
  return (1.0 - w) * value[k - 1] + w * value[k];
}

/// `value` with `decimals` decimals, never "-0.000".
std::string fixed(double value, int decimals) {
  const double scale = std::pow(10.0, decimals);
  const double rounded = std::round(value * scale) / scale;
  return fmt::format("{:.{}f}", rounded == 0.0 ? 0.0 : rounded, decimals);
}

/// A value of `term` (um or urad inside) as the file has it (mm or rad).
std::string fileValue(double value, bool angle) {
  return angle ? fixed(value * kRadPerUrad, 10) : fixed(value * kMmPerUm, 7);
}

}  // namespace

std::size_t VolumetricTable::records() const {
  std::size_t n = constants.empty() ? 0 : 1;
  for (const auto& a : axes) n += a.position.size();
  return n;
}

Eigen::VectorXd VolumetricTable::errorsAt(const MultibodyModel& kinematics, const Eigen::VectorXd& q) const {
  Eigen::VectorXd e = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(kinematics.terms().size()));
  const auto& coordinates = kinematics.coordinates();
  for (const auto& axis : axes) {
    const auto c = std::find(coordinates.begin(), coordinates.end(), axis.coordinate);
    if (c == coordinates.end())
      throw InputError(fmt::format("the machine '{}' has no axis {} (the compensation has)", kinematics.name(),
                                   upper(axis.coordinate[0])));
    const double at = q(c - coordinates.begin());
    for (const auto& [term, values] : axis.values)
      e(kinematics.termIndex(term)) = interpolate(axis.position, values, at);
  }
  for (const auto& [term, value] : constants) e(kinematics.termIndex(term)) = value;
  return e;
}

VolumetricTable sampleVolumetric(const ErrorModel& model, double interval) {
  checkInterval(interval, "volumetric compensation");
  const auto& kinematics = model.kinematics();
  const auto& terms = kinematics.terms();
  const Eigen::VectorXd centre = model.workspaceCentre();
  VolumetricTable table;
  const Eigen::VectorXd at_centre = model.errorsAt(centre);
  for (std::size_t t = 0; t < terms.size(); ++t) {
    if (!terms[t].motion) table.constants[terms[t].name] = at_centre(static_cast<Eigen::Index>(t));
  }
  for (std::size_t c = 0; c < kinematics.coordinates().size(); ++c) {
    std::vector<std::size_t> of_axis;
    for (std::size_t t = 0; t < terms.size(); ++t) {
      if (terms[t].motion && kinematics.coordinateOfJoint(terms[t].joint) == static_cast<int>(c)) of_axis.push_back(t);
    }
    const auto [from, to] = model.coordinateRange(static_cast<int>(c));
    if (of_axis.empty() || !(to > from)) continue;
    VolumetricTable::AxisBlock block;
    block.coordinate = kinematics.coordinates()[c];
    const auto rows = static_cast<std::size_t>(std::ceil((to - from) / interval - 1e-9)) + 1;
    Eigen::VectorXd q = centre;
    for (std::size_t r = 0; r < rows; ++r) {
      q(static_cast<Eigen::Index>(c)) = std::min(to, from + static_cast<double>(r) * interval);
      block.position.push_back(q(static_cast<Eigen::Index>(c)));
      const Eigen::VectorXd e = model.errorsAt(q);
      for (const auto t : of_axis) block.values[terms[t].name].push_back(e(static_cast<Eigen::Index>(t)));
    }
    table.axes.push_back(std::move(block));
  }
  return table;
}

std::array<double, 3> volumetricCorrectionUm(const MultibodyModel& kinematics, const VolumetricTable& table,
                                             const Eigen::VectorXd& q, const std::array<int, 3>& positioning_terms) {
  const Eigen::VectorXd errors = table.errorsAt(kinematics, q);
  const Eigen::Vector3d e = kinematics.spatialErrorUm(q, errors);
  const Eigen::Matrix3Xd jacobian = kinematics.jacobian(q);
  Eigen::Matrix3d positioning;
  for (int a = 0; a < 3; ++a) positioning.col(a) = jacobian.col(positioning_terms[static_cast<std::size_t>(a)]);
  // E(errors + d on the positioning errors) = E(errors) + positioning d = 0.
  const Eigen::Vector3d d = positioning.colPivHouseholderQr().solve(-e);
  return {d(0), d(1), d(2)};
}

std::string writeIsgVolumetricCsv(const VolumetricTable& table, const std::string& comment) {
  std::string out;
  std::istringstream comments(comment);
  for (std::string line; std::getline(comments, line);) out += "// " + line + "\n";
  out += "// ISO 230-1 component errors per axis and position errors; mm and rad, arguments mm (deg)\n";
  bool first_block = true;
  auto block_break = [&] {
    if (!first_block) out += "#\n";
    first_block = false;
  };
  for (const auto& axis : table.axes) {
    const char letter = upper(axis.coordinate[0]);
    block_break();
    out += letter;
    for (const auto& [term, values] : axis.values) out += " " + isgName(term, true);
    out += "\n";
    for (std::size_t r = 0; r < axis.position.size(); ++r) {
      out += fixed(axis.position[r], 4);
      for (const auto& [term, values] : axis.values) out += " " + fileValue(values[r], isAngle(term));
      out += "\n";
    }
  }
  if (!table.constants.empty()) {
    block_break();
    std::string names, values;
    for (const auto& [term, value] : table.constants) {
      names += (names.empty() ? "" : " ") + isgName(term, false);
      // A position error's first letter is what it is: a rotation (A, B, C) or an offset.
      values += (values.empty() ? "" : " ") + fileValue(value, isRotary(term[1]));
    }
    out += names + "\n" + values + "\n";
  }
  return out;
}

VolumetricTable readIsgVolumetricCsv(std::string_view text, const std::string& source) {
  using format_text::numberOf;
  const auto lines = format_text::linesOf(text);
  VolumetricTable table;
  std::set<std::string> seen;
  std::vector<std::string> header;  // of the block being read; empty: the next line is a header
  std::size_t header_line = 0, rows_of_block = 0;
  auto end_block = [&] {
    if (!header.empty() && rows_of_block == 0)
      throw InputError(fmt::format("{}: line {}: a header without records", source, header_line));
    header.clear();
  };
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::size_t n = i + 1;
    std::string line = lines[i];
    if (const auto slash = line.find("//"); slash != std::string::npos) line.erase(slash);
    if (!line.empty() && line.find_first_not_of(" \t") != std::string::npos &&
        line[line.find_first_not_of(" \t")] == '#') {
      end_block();
      continue;
    }
    const auto tokens = tokensOf(line);
    if (tokens.empty()) continue;
    if (header.empty()) {
      header = tokens;
      header_line = n;
      rows_of_block = 0;
      const bool argument = header[0].size() == 1 && isAxisLetter(header[0][0]);
      for (std::size_t k = 0; k < header.size(); ++k) {
        const std::string& name = header[k];
        const bool component = name.size() == 3 && name[0] == 'E' && isAxisLetter(name[1]) && isAxisLetter(name[2]);
        const bool position = name.size() == 3 && isAxisLetter(name[0]) && name[1] == '0' && isAxisLetter(name[2]);
        if (k == 0 && argument) continue;
        if (name.size() == 1 && isAxisLetter(name[0]))
          throw InputError(
              fmt::format("{}: line {}: a second argument '{}': mtcal reads blocks of one argument", source, n, name));
        if (!component && !position)
          throw InputError(fmt::format("{}: line {}: unknown identifier '{}'", source, n, name));
        if (component && (!argument || name[2] != header[0][0]))
          throw InputError(fmt::format("{}: line {}: '{}' depends on {}, not on the block's argument '{}'", source, n,
                                       name, name[2], argument ? header[0] : "(none)"));
        if (position && argument)
          throw InputError(
              fmt::format("{}: line {}: the position error '{}' in a block of argument {}: mtcal reads "
                          "position errors as constants, in a block of their own",
                          source, n, name, header[0]));
        if (!seen.insert(name).second)
          throw InputError(fmt::format("{}: line {}: '{}' is given twice", source, n, name));
      }
      if (argument) {
        if (header.size() == 1) throw InputError(fmt::format("{}: line {}: an argument without errors", source, n));
        table.axes.push_back({std::string(1, lower(header[0][0])), {}, {}});
      }
      continue;
    }
    if (tokens.size() != header.size())
      throw InputError(fmt::format("{}: line {}: {} values for the {} columns of line {}", source, n, tokens.size(),
                                   header.size(), header_line));
    std::vector<double> values;
    for (const auto& t : tokens) {
      values.push_back(numberOf(t, source, n));
      // In um and urad inside: a value beyond that range is no machine's error.
      if (std::abs(values.back()) > 1e300)
        throw InputError(fmt::format("{}: line {}: '{}' is out of range", source, n, t));
    }
    ++rows_of_block;
    const bool argument = header[0].size() == 1;
    if (!argument) {
      if (rows_of_block > 1)
        throw InputError(
            fmt::format("{}: line {}: position errors are constants: one record, not {}", source, n, rows_of_block));
      for (std::size_t k = 0; k < header.size(); ++k)
        table.constants["E" + header[k]] = values[k] / (isRotary(header[k][0]) ? kRadPerUrad : kMmPerUm);
      continue;
    }
    auto& axis = table.axes.back();
    if (!axis.position.empty() && !(values[0] > axis.position.back()))
      throw InputError(fmt::format("{}: line {}: {} = {} does not increase (previous {})", source, n, header[0],
                                   values[0], axis.position.back()));
    axis.position.push_back(values[0]);
    for (std::size_t k = 1; k < header.size(); ++k)
      axis.values[header[k]].push_back(values[k] / (isAngle(header[k]) ? kRadPerUrad : kMmPerUm));
  }
  end_block();
  if (table.axes.empty() && table.constants.empty())
    throw InputError(fmt::format("{}: no records (a header line, then rows of numbers)", source));
  std::set<std::string> axes_seen;
  for (const auto& a : table.axes) {
    if (!axes_seen.insert(a.coordinate).second)
      throw InputError(
          fmt::format("{}: two blocks of argument {}: mtcal reads one per axis", source, upper(a.coordinate[0])));
  }
  return table;
}

std::string isgVolumetricSetup(const VolumetricTable& table, const std::string& file_name) {
  std::string out =
      "# lines of the volumetric compensation's configuration list (the file that vol_comp[0].file_name names in "
      "the start-up list)\n"
      "# axis assignment: ISO 230 axis, the controller's logical axis number (check them)\n";
  int number = 1;
  for (const auto& a : table.axes) out += fmt::format("{} {}\n", upper(a.coordinate[0]), number++);
  out += fmt::format("file[0] {}\nfile_format[0] ISG_CSV\n", file_name);
  out += fmt::format("# start-up list: at least this many records\nvol_comp[0].max_records {}\n", table.records());
  return out;
}

}  // namespace mtcal::processing
