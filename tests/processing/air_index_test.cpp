#include "mtcal/processing/air_index.h"

#include <gtest/gtest.h>

#include <cmath>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

// NIST Engineering Metrology Toolbox, "Refractive Index of Air Calculator" (Stone &
// Zimmerman), modified Edlen at its defaults: 633 nm vacuum, 20 degC, 101 325 Pa, 50 % RH,
// 450 umol/mol CO2 -> n = 1.000271374.
TEST(AirIndex, EdlenMatchesNistCalculatorAtStandardConditions) {
  EXPECT_NEAR(edlenIndex({20.0, 101325.0, 50.0, 450.0}, 633.0), 1.000271374, 1e-9);
}

// Sensitivities near 20 degC at 633 nm quoted with the NIST calculator: about -0.95 ppm/K,
// +0.27 ppm/hPa, -0.0085 ppm/%RH (the rules of thumb every laser calibrator uses).
TEST(AirIndex, EdlenSensitivitiesMatchPublishedRulesOfThumb) {
  const AirState base{20.0, 101325.0, 50.0, 450.0};
  const double n0 = edlenIndex(base, 633.0);
  AirState warm = base;
  warm.temperature_c += 1.0;
  AirState high = base;
  high.pressure_pa += 100.0;
  AirState humid = base;
  humid.humidity_pct += 10.0;
  EXPECT_NEAR((edlenIndex(warm, 633.0) - n0) * 1e6, -0.95, 0.01);
  EXPECT_NEAR((edlenIndex(high, 633.0) - n0) * 1e6, 0.27, 0.005);
  EXPECT_NEAR((edlenIndex(humid, 633.0) - n0) * 1e6 / 10.0, -0.0085, 0.0005);
}

// Ciddor 1996, eq. (1): standard air (15 degC, 101 325 Pa, dry, 450 ppm CO2) has
// (n - 1) = 0.05792105/(238.0185 - s^2) + 0.00167917/(57.362 - s^2). At exactly those
// conditions the full equation must reduce to it (the density ratio is 1 by construction).
TEST(AirIndex, CiddorReducesToStandardAirDispersionFormula) {
  const double sigma2 = std::pow(1.0 / 0.633, 2);
  const double standard = 0.05792105 / (238.0185 - sigma2) + 0.00167917 / (57.362 - sigma2);
  EXPECT_NEAR(ciddorIndex({15.0, 101325.0, 0.0, 450.0}, 633.0) - 1.0, standard, 2e-11);
}

// NIST Engineering Metrology Toolbox, "Index of Refraction of Air" (J. A. Stone and J. H.
// Zimmerman), documentation section VII, "Comparison of Ciddor and Modified Edlen
// Equations", table of n computed by the NIST calculator (CO2 450 umol/mol): temperature,
// relative humidity, pressure, vacuum wavelength, n (Ciddor), n (modified Edlen).
// https://emtoolbox.nist.gov/Wavelength/Documentation.asp. Printed to 1e-9: the tolerance is
// that rounding plus 5e-10. The humid rows carry the saturation pressure and the water terms;
// in four rows (-40 degC; 50 degC at 100 %; 40 degC at 100 % and 300 nm) the two equations
// differ by 6e-8 to 1.6e-7, 60 to 160 times the tolerance, so each is told from the other.
struct NistRow {
  double t_c, rh_pct, p_kpa, lambda_nm, n_ciddor, n_edlen;
};
constexpr NistRow kNistTable[] = {
    {20, 0, 101.325, 633, 1.000271800, 1.000271799},  {20, 0, 60, 633, 1.000160924, 1.000160920},
    {20, 0, 120, 633, 1.000321916, 1.000321918},      {50, 0, 100, 633, 1.000243285, 1.000243270},
    {5, 0, 100, 633, 1.000282756, 1.000282750},       {-40, 0, 100, 633, 1.000337580, 1.000337471},
    {50, 100, 120, 633, 1.000287924, 1.000287864},    {40, 75, 120, 633, 1.000299418, 1.000299406},
    {20, 100, 100, 633, 1.000267394, 1.000267394},    {40, 100, 110, 1700, 1.000270247, 1.000270237},
    {20, 0, 101.325, 1700, 1.000268479, 1.000268483}, {40, 100, 110, 300, 1.000289000, 1.000288922},
    {20, 0, 101.325, 300, 1.000286581, 1.000286579},  {-40, 0, 120, 300, 1.000427233, 1.000427072},
};

TEST(AirIndex, BothEquationsMatchTheNistComparisonTable) {
  for (const NistRow& r : kNistTable) {
    const AirState air{r.t_c, r.p_kpa * 1000.0, r.rh_pct, 450.0};
    EXPECT_NEAR(ciddorIndex(air, r.lambda_nm), r.n_ciddor, 1e-9)
        << r.t_c << " degC " << r.rh_pct << " % " << r.p_kpa << " kPa " << r.lambda_nm << " nm";
    EXPECT_NEAR(edlenIndex(air, r.lambda_nm), r.n_edlen, 1e-9)
        << r.t_c << " degC " << r.rh_pct << " % " << r.p_kpa << " kPa " << r.lambda_nm << " nm";
  }
}

// Ciddor, Applied Optics 35, 1566 (1996): (n - 1) x 1e8 at 633 nm and 450 umol/mol CO2 by the
// new equations, Table 1 (dry air, 10 to 30 degC, 80 to 120 kPa) and Table 3 (moist air at
// extreme conditions, 20 to 50 degC, 75 and 100 % RH; its row 40 degC, 80 kPa, 75 % is left
// out, its value being quoted inconsistently). Printed to 0.1, that is 1e-9 in n: tolerance
// 0.1 (the rounding plus as much again).
TEST(AirIndex, CiddorMatchesCiddorsTables) {
  struct Row {
    double t_c, p_kpa, rh_pct, refractivity_1e8;
  };
  const Row rows[] = {
      {20, 80, 0, 21458.0},   {20, 100, 0, 26824.4},   {20, 120, 0, 32191.6},  {10, 100, 0, 27774.7},
      {30, 100, 0, 25937.2},  {20, 80, 75, 21394.0},   {20, 120, 75, 32127.8}, {40, 120, 75, 29941.8},
      {50, 80, 100, 19058.4}, {50, 120, 100, 28792.4},
  };
  for (const Row& r : rows) {
    const double n = ciddorIndex({r.t_c, r.p_kpa * 1000.0, r.rh_pct, 450.0}, 633.0);
    EXPECT_NEAR((n - 1.0) * 1e8, r.refractivity_1e8, 0.1)
        << r.t_c << " degC " << r.p_kpa << " kPa " << r.rh_pct << " %";
  }
}

// NIST documents that the two equations agree within about 1e-8 for ordinary shop air.
TEST(AirIndex, CiddorAndEdlenAgreeInShopConditions) {
  for (double t : {18.0, 20.0, 24.0}) {
    for (double p : {95000.0, 101325.0, 104000.0}) {
      for (double h : {20.0, 50.0, 80.0}) {
        const AirState air{t, p, h, 450.0};
        EXPECT_NEAR(ciddorIndex(air, 632.991), edlenIndex(air, 632.991), 2e-8) << t << " " << p << " " << h;
      }
    }
  }
}

// CO2, by hand from published values: in Ciddor's equations (1996, eqs. 2-4) the CO2 content
// scales the standard dry-air refractivity by 1 + 0.534e-6 (x - 450) (eq. 2, x in umol/mol);
// the molar mass of the air M_a(x) enters both the air's density and that of standard air at
// the same x, and cancels in their ratio. So for dry air at fixed T and p, (n - 1) at x
// equals (n - 1) at 450 umol/mol times that factor. From NIST's table value for 20 degC,
// 101.325 kPa, dry, 633 nm, n - 1 = 2.71800e-4:
//   750 umol/mol: 2.71800e-4 x (1 + 0.534e-6 x 300) = 2.718435e-4 (+4.35e-8),
//   300 umol/mol: 2.71800e-4 x (1 - 0.534e-6 x 150) = 2.717782e-4 (-2.18e-8).
// The tolerance (the table's rounding, 5e-10, plus 5e-10) is 2 % of the 750 umol/mol effect.
TEST(AirIndex, CarbonDioxideScalesTheDryAirRefractivityAsCiddorsEquation2) {
  EXPECT_NEAR(ciddorIndex({20.0, 101325.0, 0.0, 750.0}, 633.0), 1.0002718435, 1e-9);
  EXPECT_NEAR(ciddorIndex({20.0, 101325.0, 0.0, 300.0}, 633.0), 1.0002717782, 1e-9);
  // The modified Edlen equation takes the same factor (its own calculator fixes 450).
  EXPECT_NEAR(edlenIndex({20.0, 101325.0, 0.0, 750.0}, 633.0) - edlenIndex({20.0, 101325.0, 0.0, 450.0}, 633.0),
              4.35e-8, 0.02e-8);
}

// IAPWS-IF97 saturation pressure: 2339.3 Pa at 20 degC (steam tables) and 0.101418 MPa
// at 100 degC (IF97 verification table).
TEST(AirIndex, SaturationVapourPressureMatchesSteamTables) {
  EXPECT_NEAR(saturationVapourPressurePa(20.0), 2339.3, 0.5);
  EXPECT_NEAR(saturationVapourPressurePa(100.0), 101418.0, 2.0);
  // Triple point (273.16 K = 0.01 degC): 611.657 Pa.
  EXPECT_NEAR(saturationVapourPressurePa(0.01), 611.657, 0.1);
}

// Over ice: the IAPWS 2011 sublimation equation (IAPWS R14-08(2011), eq. 6; Wagner, Riethmann,
// Feistel & Harvey, J. Phys. Chem. Ref. Data 40, 043103, 2011),
//   ln(p / 611.657 Pa) = theta^-1 (a1 theta^b1 + a2 theta^b2 + a3 theta^b3), theta = T / 273.16 K,
//   a = (-21.2144006, 27.3203819, -6.10598130), b = (0.00333333333, 1.20666667, 1.70333333).
// The release's verification value: 230 K -> 8.94735e-6 MPa. Evaluated by hand from the
// equation: 12.84117 Pa at -40 degC, 103.23903 Pa at -20 degC, 401.74102 Pa at -5 degC.
// The older two-term equation (IAPWS 1993; Wagner, Saul & Pruss, J. Phys. Chem. Ref. Data 23,
// 515, 1994: ln(p / p_t) = -13.928169 (1 - theta^-1.5) + 34.7078238 (1 - theta^-1.25), the one
// of NIST EMT Appendix A-I) gives 8.94653, 12.84129, 103.26013 and 401.76375 Pa: the
// tolerances (1e-5 Pa and 1e-4 Pa, the rounding of the values above) tell the two apart at
// every point (by 8e-4, 1.2e-4, 0.021 and 0.023 Pa).
TEST(AirIndex, SublimationPressureIsTheIapws2011Equation) {
  EXPECT_NEAR(saturationVapourPressurePa(230.0 - 273.15), 8.94735, 1e-5);
  EXPECT_NEAR(saturationVapourPressurePa(-40.0), 12.84117, 1e-5);
  EXPECT_NEAR(saturationVapourPressurePa(-20.0), 103.23903, 1e-4);
  EXPECT_NEAR(saturationVapourPressurePa(-5.0), 401.74102, 1e-4);
}

TEST(AirIndex, RejectsInputsOutsideTheValidRangeWithTheirName) {
  try {
    edlenIndex({20.0, 101325.0, 120.0, 450.0}, 633.0);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("relative humidity"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ciddorIndex({20.0, 101325.0, 50.0, 450.0}, 200.0), InputError);
  EXPECT_THROW(ciddorIndex({150.0, 101325.0, 50.0, 450.0}, 633.0), InputError);
}

// Normal temperature correction, hand-worked: a steel bar (alpha 11.5e-6 /K) 500 mm long at
// 20 degC is 11.5e-6 x 500 mm x 1 K = 5.75 um longer at 21 degC, 500.00575 mm; normalised
// it must be 500 mm again. An aluminium bar (23e-6 /K) of 1000 mm at 20 degC is 46 um
// shorter at 18 degC, 999.954 mm. Both exactly (to 1 pm): the linearised correction
// L_t (1 - alpha (t - 20)) would be off by L alpha^2 (t - 20)^2 = 66 pm and 2.1 nm.
TEST(Compensation, NormalTemperatureCorrectionByHand) {
  EXPECT_NEAR(normaliseTo20C(500.00575, 21.0, 11.5e-6), 500.0, 1e-9);
  EXPECT_NEAR(normaliseTo20C(999.954, 18.0, 23e-6), 1000.0, 1e-9);
  EXPECT_DOUBLE_EQ(normaliseTo20C(500.0, 20.0, 11.5e-6), 500.0);
}

// Wavelength compensation, hand-worked: a 100 mm move in NIST's default air (20 degC,
// 101 325 Pa, 50 % RH, 633 nm: n = 1.000271374, NIST EMT Edlen calculator) is
// 2 x 100 mm x n / 633 nm = 316 041.508 fringes; an instrument that counts them with the
// vacuum wavelength reads 316 041.508 x 633 nm / 2 = 100.0271374 mm. Compensated, 100 mm
// (to 1 pm; the linearised L_raw (2 - n) would be 7.4 nm short).
TEST(Compensation, WavelengthCompensationByHand) {
  EXPECT_NEAR(compensateWavelength(100.0271374, 1.000271374), 100.0, 1e-9);
}

}  // namespace
}  // namespace mtcal::processing
