#pragma once
// Numbers as people read them: significant digits, and a value beside its standard error.

#include <string>

namespace mtcal::processing {

/// A number to `digits` significant digits, its trailing zeros kept and without an exponent
/// from 1e-6 to a million (the %g form writes 190 to two digits as 1.9e+02, and -3.000 as -3
/// beside 4.001); beyond, the exponent form.
std::string significant(double value, int digits);

/// `value` rounded to `decimals` decimals, a negative value that rounds to zero made zero: printed
/// with that many decimals, never "-0.00".
double roundedTo(double value, int decimals);

/// A value and its standard error: the standard error to two significant digits, the value to
/// the standard error's last digit (GUM 7.2.6: 0.35 +- 0.40, not 0.3484 +- 0.40; 1040 +- 190 s;
/// 5.00001 +- 0.00082 mm, not 5.000; 0.002370 +- 0.000016 um, not 0.002370 +- 1.6e-05), in fixed
/// form where the standard error is from 1e-6 to a million and the value below a million; beyond,
/// both in the power of ten of the larger ((3.200 +- 0.046)e7), or where they are more than 1e4
/// apart each to its own digits; without a standard error (0 or none), the value alone.
/// `separator`: " +- " in text, " ± " in a report.
std::string valueWithUncertainty(double value, double standard_error, const std::string& separator = " +- ");

/// A size of a residual: to the nanometre, and to three significant digits below 0.1 (an EST
/// run's probes read a few nanometres: 0.0135 -> 0.00245, not 0.013 -> 0.002).
std::string sizeText(double value);

}  // namespace mtcal::processing
