#include "mtcal/processing/compensation_formats.h"

#include <fmt/format.h>

#include <sstream>

#include "compensation_text.h"
#include "mtcal/error.h"
#include "mtcal/processing/number_text.h"

namespace mtcal::processing {
namespace {

using namespace format_text;

// --- LinuxCNC: [JOINT_n] COMP_FILE, three numbers a line, in machine units (mm) ---------------

constexpr std::size_t kLinuxCncMaxEntries = 256;

ControllerFile writeLinuxCnc(const CompensationTable& t, const AxisOfTable& axis, int file_type) {
  if (t.modulo) throw InputError("LinuxCNC: a comp file has no modulo (rotary axes are compensated over their range)");
  ControllerFile f;
  f.extension = ".comp";
  for (std::size_t i = 0; i < t.position.size(); ++i) {
    const double up_mm = t.up_um[i] / kUmPerMm, down_mm = t.down_um[i] / kUmPerMm;
    // Type 0 holds where the axis actually is (the trim applied is nominal - actual), type 1 the trims.
    if (file_type == 0) {
      f.text += fmt::format("{:.6f} {:.6f} {:.6f}\n", t.position[i], t.position[i] - up_mm, t.position[i] - down_mm);
    } else {
      f.text += fmt::format("{:.6f} {:.6f} {:.6f}\n", t.position[i], up_mm, down_mm);
    }
  }
  f.setup = fmt::format(
      "[JOINT_{0}]\n"
      "# axis {1}: {2} entries from {3:g} to {4:g} mm; BACKLASH is ignored with a COMP_FILE\n"
      "COMP_FILE = {5}\n"
      "COMP_FILE_TYPE = {6}\n",
      axis.index, axis.name, t.position.size(), t.position.front(), t.position.back(), axis.fileName(f.extension),
      file_type);
  return f;
}

CompensationTable readLinuxCnc(std::string_view text, const std::string& source, int file_type) {
  CompensationTable t;
  const auto lines = linesOf(text);
  std::size_t last = lines.size();
  while (last > 0 && lines[last - 1].find_first_not_of(" \t") == std::string::npos) --last;  // trailing blanks
  for (std::size_t i = 0; i < last; ++i) {
    const auto v = leadingNumbers(lines[i], 3);
    if (v.size() < 3) {
      throw InputError(
          fmt::format("{}: line {}: '{}' is not three numbers: LinuxCNC ends the table there without a "
                      "word and would load {} entries (no header or comment lines in a comp file)",
                      source, i + 1, lines[i], t.position.size()));
    }
    if (!t.position.empty() && !(v[0] > t.position.back())) {
      throw InputError(
          fmt::format("{}: line {}: nominal {:g} does not increase: LinuxCNC rejects the entry", source, i + 1, v[0]));
    }
    t.position.push_back(v[0]);
    t.up_um.push_back((file_type == 0 ? v[0] - v[1] : v[1]) * kUmPerMm);
    t.down_um.push_back((file_type == 0 ? v[0] - v[2] : v[2]) * kUmPerMm);
  }
  if (t.position.size() > kLinuxCncMaxEntries) {
    throw InputError(
        fmt::format("{}: {} entries: LinuxCNC takes at most {}", source, t.position.size(), kLinuxCncMaxEntries));
  }
  checkTable(t, source.c_str());
  return t;
}

// --- Generic CSV: the error and the correction per direction, um ------------------------------

ControllerFile writeCsv(const CompensationTable& t, const AxisOfTable&) {
  ControllerFile f;
  f.extension = ".csv";
  f.text = "position,error_up_um,error_down_um,correction_up_um,correction_down_um\n";
  for (std::size_t i = 0; i < t.position.size(); ++i) {
    // The position to 0.1 um (what the read-back holds it to), without trailing zeros; the values
    // to 0.1 nm, a zero without a sign.
    std::string position = fmt::format("{:.4f}", roundedTo(t.position[i], 4));
    position.erase(position.find_last_not_of('0') + 1);
    if (position.back() == '.') position.pop_back();
    f.text += fmt::format("{},{:.4f},{:.4f},{:.4f},{:.4f}\n", position, roundedTo(-t.up_um[i], 4),
                          roundedTo(-t.down_um[i], 4), roundedTo(t.up_um[i], 4), roundedTo(t.down_um[i], 4));
  }
  return f;
}

CompensationTable readCsv(std::string_view text, const std::string& source) {
  const auto lines = linesOf(text);
  const std::string header = "position,error_up_um,error_down_um,correction_up_um,correction_down_um";
  if (lines.empty() || lines[0] != header)
    throw InputError(fmt::format("{}: line 1: the header is not '{}'", source, header));
  CompensationTable t;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    if (lines[i].empty()) continue;
    std::vector<double> v;
    std::stringstream row(lines[i]);
    std::string cell;
    while (std::getline(row, cell, ',')) {
      const auto n = leadingNumbers(cell, 1);
      if (n.empty()) throw InputError(fmt::format("{}: line {}: '{}' is not a number", source, i + 1, cell));
      v.push_back(n[0]);
    }
    if (v.size() != 5) throw InputError(fmt::format("{}: line {}: {} columns, not 5", source, i + 1, v.size()));
    t.position.push_back(v[0]);
    t.up_um.push_back(v[3]);
    t.down_um.push_back(v[4]);
  }
  checkTable(t, source.c_str());
  return t;
}

/// LinuxCNC's format of COMP_FILE_TYPE `kFileType` (src/emc/motion/control.c: linear between
/// entries, the end values held beyond them, the forward trim while the commanded velocity is
/// positive).
template <int kFileType>
ControllerFormat linuxCnc(const char* name, const char* columns) {
  return {name,
          fmt::format("LinuxCNC comp file, COMP_FILE_TYPE {}: {}", kFileType, columns),
          {true, true},
          kLinuxCncMaxEntries,
          0.0,
          [](const CompensationTable& t, const AxisOfTable& a) { return writeLinuxCnc(t, a, kFileType); },
          [](std::string_view text, const std::string& source) { return readLinuxCnc(text, source, kFileType); }};
}

const std::vector<ControllerFormat>& formats() {
  static const std::vector<ControllerFormat> all{
      {"csv", "generic CSV: position, error and correction per direction (um)", {}, 0, 0.0, writeCsv, readCsv},
      linuxCnc<0>("linuxcnc", "nominal, actual position forward, actual position reverse (mm)"),
      linuxCnc<1>("linuxcnc-trim", "nominal, forward trim, reverse trim (mm)"),
      siemensEecFormat(),
      siemensCecFormat(),
      heidenhainFormat(),
      fanucFormat(),
      twincatPtpFormat(),
      twincatCncFormat(),
  };
  return all;
}

}  // namespace

const ControllerFormat& controllerFormat(std::string_view name) {
  for (const auto& f : formats())
    if (f.name == name) return f;
  if (name == kIsgVolumetric)
    throw InputError(
        fmt::format("{} is a model's volumetric table (every axis in one file), not one axis' table "
                    "(the axis' formats: {})",
                    kIsgVolumetric, fmt::join(controllerNames(), ", ")));
  throw InputError(fmt::format("unknown controller '{}' (one of: {}; of a model, also {}: its volumetric table)", name,
                               fmt::join(controllerNames(), ", "), kIsgVolumetric));
}

std::vector<std::string> controllerNames() {
  std::vector<std::string> names;
  for (const auto& f : formats()) names.push_back(f.name);
  return names;
}

}  // namespace mtcal::processing
