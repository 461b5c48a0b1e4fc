#pragma once
// What the controller formats share: reading a file's lines and numbers, and the checks that
// several controllers make of a table. Private to processing.

#include <string>
#include <string_view>
#include <vector>

#include "mtcal/processing/compensation_formats.h"

namespace mtcal::processing::format_text {

constexpr double kUmPerMm = 1000.0;

/// The lines of a text, without their line ends ("\n" or "\r\n").
std::vector<std::string> linesOf(std::string_view text);

/// The numbers a line starts with, as C's strtod reads them (how sscanf's %lf reads a LinuxCNC
/// table line): at most `count`.
std::vector<double> leadingNumbers(const std::string& line, std::size_t count);

/// `text` as one number and nothing else. @throws InputError "source: line N: 'text' is not a number"
double numberOf(std::string_view text, const std::string& source, std::size_t line);

/// The spacing of a table whose controller needs equidistant entries. @throws InputError naming
/// the controller and the first entry off the grid
double equidistantStep(const CompensationTable& table, std::string_view controller);

/// Refuses a bidirectional table for a controller that applies one table to both directions,
/// naming what to do instead. @throws InputError
void requireOneTable(const CompensationTable& table, std::string_view controller, std::string_view instead);

/// The positions of `count` entries from `first`, `step` apart.
std::vector<double> gridPositions(double first, double step, std::size_t count);

/// A modulo table with its period's end as one more entry, holding the first entry's values
/// (the closed form Siemens, Fanuc and TwinCAT tables of a rotary axis take); others unchanged.
CompensationTable withPeriodEnd(const CompensationTable& table);

/// A table read from a file: the entries checked, the modulo's repeated last entry removed
/// (a table of the period's length whose last value equals the first).
CompensationTable closedTable(CompensationTable table, bool modulo, const std::string& source);

// The controllers' formats besides LinuxCNC and the generic CSV, one per vendor file.
ControllerFormat siemensEecFormat();
ControllerFormat siemensCecFormat();
ControllerFormat heidenhainFormat();
ControllerFormat fanucFormat();
ControllerFormat twincatPtpFormat();
ControllerFormat twincatCncFormat();

}  // namespace mtcal::processing::format_text
