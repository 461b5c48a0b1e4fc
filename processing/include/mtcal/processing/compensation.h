#pragma once
// Axis compensation tables: built from an axis' measured positioning error, and the correction
// a controller applies from one while the axis moves. Pure functions, thread-safe.
//
// Signs: an error is actual minus commanded position (ISO 230-2's deviation x_ij = P_ij - P_i);
// a correction is what the controller adds to the commanded position, so a table that cancels
// an error e holds -e. Positions are mm on a linear axis, deg on a rotary one; errors and
// corrections are um on a linear axis (the unit is the caller's on a rotary one).

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/processing/iso230_2.h"

namespace mtcal::processing {

/// An axis' positioning error per approach direction, at strictly increasing positions.
struct AxisError {
  std::vector<double> position;
  std::vector<double> up_um, down_um;  ///< moving in the positive / negative direction

  /// Linear between the positions. @throws InputError outside them
  double at(double position, Direction direction) const;
};

/// The error of each target of an ISO 230-2 evaluation: the mean deviation per direction
/// (x-bar up and down); a direction that was not measured takes the other's.
/// @throws InputError when a target has neither direction
AxisError axisErrorOf(const Iso230Result& evaluation);

/// How a controller turns its table into a correction between and beyond the entries.
struct TableRules {
  /// Between two entries: linear interpolation (true), or the value of the entry on the
  /// negative side held up to the next entry (false: a step at each entry).
  bool interpolate = true;
  /// Beyond the first and last entries: their values held (true) or no correction (false).
  bool hold_beyond = true;
};

/// A compensation table: the correction a controller adds to the commanded position, at
/// strictly increasing positions, per direction of travel (equal when not bidirectional).
struct CompensationTable {
  std::vector<double> position;
  std::vector<double> up_um, down_um;
  /// A rotary axis' period (deg, e.g. 360): positions are taken modulo it into [first entry,
  /// first entry + period), and past the last entry the values run to the first entry's.
  std::optional<double> modulo;
  /// The axis as a file read names it (SINUMERIK's AX2, FANUC's A2: the controller's axis
  /// number); empty where the format names none (it is one file per axis).
  std::string axis_in_file;

  bool bidirectional() const { return up_um != down_um; }
  /// The correction at `position` while moving (or last moved) in `direction`.
  double correctionUm(double position, Direction direction, const TableRules& rules = {}) const;
};

/// The finest spacing of a table's entries (mm): a table corrects a leadscrew's errors along
/// the travel, its cycles over a lead included; an interval below is a mistyped unit.
inline constexpr double kFinestIntervalMm = 0.1;
/// The coarsest rounding of a correction (um): a controller's resolution is 0.1..1 um.
inline constexpr double kCoarsestResolutionUm = 10.0;

/// What a table is made of, besides the measured error.
struct TableOptions {
  std::optional<double> start, end;  ///< the table's first and last position (default: the measured range)
  std::optional<double> interval;    ///< spacing of the entries (default: the measured positions themselves)
  /// The correction is zero here: the mean of the two directions' corrections at this
  /// position is subtracted from every entry (a reversal stays a reversal).
  std::optional<double> reference;
  bool bidirectional = true;     ///< false: both directions get their mean
  double resolution_um = 0.0;    ///< round every correction to a multiple of this (0: no rounding)
  std::optional<double> modulo;  ///< a rotary axis' period (deg); the table then spans it
  std::size_t max_points = 0;    ///< refuse a table with more entries (0: no limit)
};

/// The table that cancels `measured`, the error of a machine that ran `existing` while it was
/// measured (nullptr: it ran none): the existing correction minus the measured error, so a
/// second iteration corrects what the first left. @throws InputError naming what is wrong
/// (positions outside the measured range, an interval that does not divide the range, more
/// entries than max_points, non-finite values)
/// Checks a table's interval (mm): positive and not finer than kFinestIntervalMm.
/// @throws InputError "`what`: the interval ..."
void checkInterval(double interval_mm, const std::string& what);

/// Checks a table's options by themselves: start, end and reference finite where given; an
/// interval positive and not finer than kFinestIntervalMm; a modulo positive; a resolution
/// 0..kCoarsestResolutionUm. @throws InputError naming the option (compensationTable checks them
/// too; a model read on the table's grid is checked first, a 1 nm interval being 10^9 readings)
void checkTableOptions(const TableOptions& options);

CompensationTable compensationTable(const AxisError& measured, const TableOptions& options,
                                    const CompensationTable* existing = nullptr, const TableRules& existing_rules = {});

/// Checks a table: at least 2 entries, strictly increasing finite positions, finite values,
/// equal lengths. @throws InputError naming `source` and the entry
void checkTable(const CompensationTable& table, const char* source);

}  // namespace mtcal::processing
