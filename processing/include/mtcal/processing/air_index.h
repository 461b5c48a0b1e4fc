#pragma once
// Refractive index of air for laser interferometry and the compensation of readings
// to the reference temperature of 20 degC.
//
// Both equations follow the formula set of J. A. Stone and J. H. Zimmerman, "Index of
// Refraction of Air", NIST Engineering Metrology Toolbox (Appendix A):
//  - modified Edlen: Birch & Downs (Metrologia 30, 1993; 31, 1994) with NIST's
//    292.75/T water-vapour term;
//  - Ciddor, Applied Optics 35, 1566 (1996).
// Pure functions, thread-safe.

namespace mtcal::processing {

/// Atmospheric state the index depends on.
struct AirState {
  double temperature_c = 20.0;    ///< air temperature, degC
  double pressure_pa = 101325.0;  ///< total pressure, Pa
  double humidity_pct = 50.0;     ///< relative humidity, %
  double co2_ppm = 450.0;         ///< CO2 mole fraction, umol/mol
};

enum class AirIndexModel { kEdlen, kCiddor };

/// The vacuum wavelengths both equations hold for, nm.
inline constexpr double kMinVacuumWavelengthNm = 300.0, kMaxVacuumWavelengthNm = 1700.0;
/// The air both equations are taken in (NIST's ranges for its calculator; Ciddor's are wider):
/// -40..100 degC, 10..140 kPa, 0..100 % relative humidity.
inline constexpr double kMinAirTemperatureC = -40.0, kMaxAirTemperatureC = 100.0;
inline constexpr double kMinAirPressurePa = 10000.0, kMaxAirPressurePa = 140000.0;
inline constexpr double kMinHumidityPct = 0.0, kMaxHumidityPct = 100.0;

/// Saturation vapour pressure over liquid water (IAPWS 1997, as used by NIST), Pa.
/// Valid 0..100 degC; below 0 degC the sublimation pressure over ice (IAPWS 2011, Wagner et al. 2011) is returned.
double saturationVapourPressurePa(double temperature_c);

/// Refractive index by the modified Edlen equation.
/// @param vacuum_wavelength_nm vacuum wavelength of the laser, nm (e.g. 632.991 for HeNe)
/// CO2 departures from 450 ppm scale the dry-air refractivity by 1 + 0.534e-6 (x - 450)
/// (Ciddor's factor; NIST's Edlen calculator itself fixes 450 ppm).
/// @throws InputError when an input is outside the range the equation is valid for
double edlenIndex(const AirState& air, double vacuum_wavelength_nm);

/// Refractive index by the Ciddor equation. @throws InputError outside the valid range.
double ciddorIndex(const AirState& air, double vacuum_wavelength_nm);

double airIndex(AirIndexModel model, const AirState& air, double vacuum_wavelength_nm);

/// Displacement along the beam from a reading the instrument computed with the vacuum
/// wavelength: the fringe count is N = 2 L n / lambda_vac, so L = L_raw / n.
inline double compensateWavelength(double raw_mm, double air_index) { return raw_mm / air_index; }

/// Normal temperature correction (ISO 1 / ISO 230-2): the length a part at material
/// temperature t would have at 20 degC, L20 = L_t / (1 + alpha (t - 20)).
/// @param expansion_per_k linear expansion coefficient, 1/K (steel about 11.5e-6)
inline double normaliseTo20C(double length_mm, double material_temp_c, double expansion_per_k) {
  return length_mm / (1.0 + expansion_per_k * (material_temp_c - 20.0));
}

}  // namespace mtcal::processing
