#pragma once
// Thermal error model of a machine from temperatures (seed 002): the drift
// delta_i = b0 + sum_r b_r u_r,i + eps_i, the inputs u either temperatures or temperatures
// through a first-order lag. Model families, compared by time-ordered cross-validation inside
// the training part and validated on the later part of the series only:
//   static   least squares, no error model;
//   ar1      eps AR(1) (eps_i = phi eps_{i-1} + a_i), b and phi by Prais-Winsten (the paper's);
//   lagged   least squares on temperatures through first-order lags (a time constant per input,
//            a sensor may enter with several: distributed lags), no error model.
// Inputs are chosen by forward selection on the cross-validated open-loop RMS, or, the paper's
// way, by grey relational analysis over clusters of correlated sensors (with the ar1 family).
// The searches see the first part of the training rows; the model kept (any family, any size)
// is the one that predicts the last part best, which no search saw: a search that tried many
// inputs is not favoured for having fitted its own folds.
//
// Predictions: open loop (b0 + sum b_r u_r,i: what a compensation knows on the machine, no
// measured error; the kept model is chosen on it) and one step ahead (the paper's eq. 7: adds
// phi times the previous measured residual; the same as open loop for a family without an
// error model). Missing values are NaN: short gaps of a temperature are interpolated, rows
// still missing a value the model needs are left out of that model.

#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace mtcal::processing {

/// Dimensionless sequences of grey relational analysis. The paper's eq. (8) is the inverse
/// range transform (max - x)/(max - min); applied to reference and comparison alike it gives
/// the same |differences| as the range transform (x - min)/(max - min), listed as kRange.
enum class GreyNormalisation { kRange, kInitialValue, kMean };
const char* greyNormalisationName(GreyNormalisation normalisation);  ///< "range", "initial", "mean"
/// @throws InputError for another name
GreyNormalisation greyNormalisationFromName(const std::string& name);

/// Grey relational grade of each column of `comparison` to `reference` (Deng):
/// xi_0i(k) = (dmin + rho dmax) / (d_0i(k) + rho dmax), d = |x0(k) - xi(k)| of the normalised
/// sequences, dmin and dmax over all columns and points; grade = mean over k.
/// @throws InputError when sizes differ, a sequence is constant (range) or has a zero
/// first value / mean (initial, mean)
Eigen::VectorXd greyRelationalGrades(const Eigen::VectorXd& reference, const Eigen::MatrixXd& comparison,
                                     GreyNormalisation normalisation, double rho = 0.5);

/// Average-linkage agglomerative clustering of the columns on the distance 1 - |r| (r their
/// correlation), cut at `clusters` clusters. @return the cluster (0..clusters-1) of each column,
/// clusters numbered in order of their first column
std::vector<int> correlationClusters(const Eigen::MatrixXd& columns, int clusters);

struct ThermalData {
  std::vector<std::string> sensors;  ///< names of the temperature columns
  Eigen::MatrixXd temperature_c;     ///< n x sensors, NaN = missing
  Eigen::VectorXd target_um;         ///< n, NaN = missing
  Eigen::VectorXd time_s;            ///< n, increasing
  /// n: the segment of each row (a resumed run starts a new one after its gap: the machine's
  /// state there is not continuous with the row before). Empty: one segment.
  std::vector<int> segment;
};

enum class ThermalFamily { kStatic, kAr1, kLagged };
const char* thermalFamilyName(ThermalFamily family);  ///< "static", "ar1", "lagged"

struct ThermalFitOptions {
  double train_fraction = 0.6;  ///< the first part of the rows fits, the rest tests
  int max_sensors = 4;          ///< the largest model's inputs (a lagged sensor counts once per lag)
  GreyNormalisation normalisation = GreyNormalisation::kRange;
  double rho = 0.5;                   ///< grey resolution coefficient
  int max_gap_samples = 3;            ///< longer gaps of a temperature stay missing
  double max_missing_fraction = 0.2;  ///< a sensor missing more of the training rows is not used
  /// The last part of the training rows: the searches (forward selection on the rolling-origin
  /// CV of the rows before it) never see it; the families and sizes are compared on it.
  double validation_fraction = 0.25;
  int cv_folds = 5;         ///< rolling origins within the search's rows
  double parsimony = 0.05;  ///< the fewest inputs within this fraction of the best validation RMS
  int ljung_box_lags = 10;
  /// Time constants tried for the lagged family (s); the temperature itself is tried too.
  std::vector<double> lag_grid_s = {600, 1200, 2400, 4800, 9600, 19200};
};

/// One model: inputs, coefficients, and how it does.
struct ThermalCandidate {
  std::string method;  ///< how its inputs were chosen: "grey", "stepwise", "all", "baseline"
  ThermalFamily family = ThermalFamily::kStatic;
  std::vector<std::string> sensors;  ///< each input's sensor, in the order of coefficients(1..)
  std::vector<int> columns;          ///< those sensors' columns of ThermalData
  std::vector<double> lag_s;         ///< each input's first-order lag time constant (0: none)
  Eigen::VectorXd coefficients;      ///< b0 (um), b_r (um/K)
  /// The level of each later segment of the training rows relative to the first (um): the
  /// displacement's zero is not continuous across a gap. A segment that starts after the
  /// training rows takes its level from its first complete row, which is not tested.
  std::map<int, double> segment_level_um;
  double phi = 0.0;             ///< AR(1) of the residual (0 without an error model)
  int n_train = 0, n_test = 0;  ///< rows used
  /// Rolling-origin cross-validation within the search's rows (the forward selection's
  /// criterion): open loop, one step ahead.
  double cv_rms_um = 0.0, cv_rms_one_step_um = 0.0;
  /// Fitted on the search's rows, predicting the validation block (the kept model's criterion).
  double validation_rms_um = 0.0, validation_rms_one_step_um = 0.0;
  double rms_train_um = 0.0, peak_train_um = 0.0;  ///< open loop on the training rows
  double rms_test_um = 0.0, peak_test_um = 0.0;    ///< open loop on the test rows
  double rms_test_one_step_um = 0.0, peak_test_one_step_um = 0.0;
  double durbin_watson = 0.0;                                 ///< of the open-loop residuals (training)
  double durbin_watson_innovations = 0.0;                     ///< of the AR(1) innovations a_i (training)
  double ljung_box_q = 0.0, ljung_box_p = 0.0;                ///< innovations, lags - 1 dof
  double ljung_box_q_static = 0.0, ljung_box_p_static = 0.0;  ///< open-loop residuals, lags dof
  double aic = 0.0, bic = 0.0;                                ///< regression + AR(1) (k = sensors + 2)
  double aic_static = 0.0, bic_static = 0.0;                  ///< regression alone (k = sensors + 1)
};

/// An input's name: its sensor, with its lag when it has one ("column_mid lag 40 min").
std::string thermalInputName(const ThermalCandidate& model, std::size_t input);
/// Every input's name, in the order of the coefficients.
std::vector<std::string> thermalInputNames(const ThermalCandidate& model);
/// The sensors a model reads, each once (a sensor entering at two lags is one), in order.
std::vector<std::string> thermalSensorsOf(const ThermalCandidate& model);

/// Models of growing size, each adding an input to the one before (or, for grey, one
/// representative per cluster).
struct ThermalPath {
  std::string method;  ///< "grey" or "stepwise"
  ThermalFamily family = ThermalFamily::kStatic;
  std::vector<ThermalCandidate> models;  ///< k = 1..max inputs
};

struct ThermalSensorStat {
  std::string name;
  double grade = 0.0;                                               ///< grey grade with the chosen normalisation
  double grade_range = 0.0, grade_initial = 0.0, grade_mean = 0.0;  ///< NaN where undefined
  double correlation = 0.0;                                         ///< with the target, training rows
  int rank = 0;                                                     ///< 1 = highest grade
  int cluster = -1;                                                 ///< at the chosen model's size; -1: not used
  int missing = 0, interpolated = 0;
  bool usable = true;
  std::string note;
};

struct ThermalFitResult {
  int n_rows = 0, n_train_rows = 0;  ///< all rows; rows before the split
  double split_time_s = 0.0;         ///< time of the first test row
  GreyNormalisation normalisation = GreyNormalisation::kRange;
  double rho = 0.5;
  std::vector<ThermalSensorStat> sensors;
  /// grey (ar1: the paper's), then forward selection in each family (static, ar1, lagged)
  std::vector<ThermalPath> paths;
  /// Every usable sensor, static least squares (absent when they are too many or dependent).
  std::optional<ThermalCandidate> all_sensors;
  ThermalCandidate baseline;  ///< the sensor most correlated with the target, static
  /// Of every path's models and all_sensors: the fewest inputs within `parsimony` of the
  /// smallest open-loop RMS on the validation block.
  ThermalCandidate chosen;
  double gain = 0.0;  ///< 1 - rms_test / rms_test of the baseline
  /// The test rows' own standard deviation: what their mean (unknown beforehand) would leave.
  double test_sd_um = 0.0;
  /// The chosen model over every row: open-loop and one-step predictions (NaN where a
  /// value is missing).
  Eigen::VectorXd predicted_open_loop_um, predicted_one_step_um;
  std::vector<std::string> notes;
};

/// The model of smallest open-loop RMS on the validation block of each path: the families compared.
std::vector<const ThermalCandidate*> bestOfEachPath(const ThermalFitResult& result);

/// Fits, selects and validates. @throws InputError when the data are too few (fewer than 20
/// training rows, or fewer than 5 test rows) or no sensor is usable
ThermalFitResult fitThermalModel(const ThermalData& data, const ThermalFitOptions& options = {});

}  // namespace mtcal::processing
