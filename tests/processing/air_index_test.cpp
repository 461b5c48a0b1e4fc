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

// CO2: Ciddor's factor 1 + 0.534e-6 (x - 450) on the dry-air refractivity.
TEST(AirIndex, MoreCarbonDioxideRaisesTheIndex) {
  const double low = ciddorIndex({20.0, 101325.0, 50.0, 300.0}, 633.0);
  const double high = ciddorIndex({20.0, 101325.0, 50.0, 600.0}, 633.0);
  EXPECT_NEAR((high - low) / 2.7e-4, 0.534e-6 * 300.0, 0.05 * 0.534e-6 * 300.0);
}

// IAPWS-IF97 saturation pressure: 2339.3 Pa at 20 degC (steam tables) and 0.101418 MPa
// at 100 degC (IF97 verification table).
TEST(AirIndex, SaturationVapourPressureMatchesSteamTables) {
  EXPECT_NEAR(saturationVapourPressurePa(20.0), 2339.3, 0.5);
  EXPECT_NEAR(saturationVapourPressurePa(100.0), 101418.0, 2.0);
  // Triple point (273.16 K = 0.01 degC): 611.657 Pa.
  EXPECT_NEAR(saturationVapourPressurePa(0.01), 611.657, 0.1);
  // Over ice (IAPWS 2011 sublimation equation): 103.26 Pa at -20 degC (Wagner, Riethmann,
  // Feistel & Harvey, J. Phys. Chem. Ref. Data 40, 043103, table of sublimation pressures).
  EXPECT_NEAR(saturationVapourPressurePa(-20.0), 103.26, 0.05);
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

// Normal temperature correction: L20 = Lt / (1 + alpha (t - 20)), closed form; and the
// wavelength compensation L = L_raw / n round-trips the emulator's L_raw = n L.
TEST(Compensation, ClosedForms) {
  EXPECT_NEAR(normaliseTo20C(500.0, 21.0, 11.5e-6), 500.0 / (1.0 + 11.5e-6), 1e-12);
  EXPECT_DOUBLE_EQ(normaliseTo20C(500.0, 20.0, 11.5e-6), 500.0);
  // 1 K on 500 mm of steel is 5.75 um.
  EXPECT_NEAR((500.0 - normaliseTo20C(500.0, 21.0, 11.5e-6)) * 1000.0, 5.75, 0.001);
  const double n = edlenIndex({20.4, 100650.0, 42.0, 450.0}, 632.991);
  EXPECT_NEAR(compensateWavelength(n * 123.456789, n), 123.456789, 1e-12);
}

}  // namespace
}  // namespace mtcal::processing
