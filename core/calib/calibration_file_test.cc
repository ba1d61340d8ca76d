#include "core/calib/calibration_file.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <string>

#include "tests/testing/test_paths.h"

namespace roomfix::calib {
namespace {

// Tolerances, each for its reason.
// A calibration written and read back maps a pixel as the original does:
// the file keeps every digit a double needs (17 significant), so only the
// mapping's own rounding of metres (~1) is left.
constexpr double kRoundTripM = 1e-12;
// The comment's worked figure is printed to 6 decimals.
constexpr double kWorkedFigurePx = 1e-6;
// At N = 100000 the finite-sample factors (N / (2N - p), 1 + p / (2N))
// still put sigma ~4e-5 px above the limit sqrt(1/2): approached, not
// reached.
constexpr double kLargeSampleLimitPx = 1e-4;

Calibration FullExample() {
  Calibration c;
  c.model = Calibration::Model::kFull;
  c.camera = NominalCamera({2.0, 1.5, 3.1}, 120.0, 1920, 1080);
  c.camera.intrinsics.k = {0.021, -0.0113, 0.0031, -0.0004};
  c.camera.intrinsics.cx_px += 3.3;
  c.camera.pose.R_room_from_camera =
      c.camera.pose.R_room_from_camera *
      Eigen::AngleAxisd(0.017, Eigen::Vector3d(1, 0.6, 0).normalized()).toRotationMatrix();
  return c;
}

std::string RegionsText(const std::string& unit, double c_x, double os2_x) {
  std::string text = "model: regions\nlength_unit: " + unit +
                     "\nwidth_px: 1920\nheight_px: 1080\ncalibration_height_m: 0.2\nregions:\n";
  for (int i = 0; i < 9; ++i) {
    text += "  - {row: " + std::to_string(i / 3) + ", col: " + std::to_string(i % 3) +
            ", x: {os1: 320, C_calib: " + std::to_string(c_x) + ", os2: " + std::to_string(os2_x) +
            "}, y: {os1: 180, C_calib: -4, os2: 250}}\n";
  }
  return text;
}

TEST(CalibrationFile, FullModelSurvivesAWriteAndReadToFullPrecision) {
  const Calibration c = FullExample();
  Calibration back;
  std::string error;
  ASSERT_TRUE(ParseCalibration(FormatCalibration(c, "a test\n\nsecond line"), "mem", &back, &error))
      << error;
  ASSERT_EQ(back.model, Calibration::Model::kFull);
  EXPECT_EQ(back.width_px(), 1920);
  EXPECT_EQ(back.height_px(), 1080);
  EXPECT_EQ(back.camera.intrinsics.k, c.camera.intrinsics.k);
  EXPECT_EQ(back.camera.intrinsics.fx_px, c.camera.intrinsics.fx_px);
  EXPECT_LT((back.camera.pose.R_room_from_camera - c.camera.pose.R_room_from_camera).norm(), 1e-15);
  double x1, y1, x2, y2;
  ASSERT_TRUE(c.PixelToFloor(1700, 900, 0.2, &x1, &y1, &error)) << error;
  ASSERT_TRUE(back.PixelToFloor(1700, 900, 0.2, &x2, &y2, &error)) << error;
  EXPECT_NEAR(x1, x2, kRoundTripM);
  EXPECT_NEAR(y1, y2, kRoundTripM);
}

// Every calibration file in config/ reads the same after roomfix writes it
// again: the rewritten text parses to a calibration that writes the same
// text, and its doubles are the file's bit for bit (17 digits map distinct
// doubles to distinct text, so equal texts mean equal values).
TEST(CalibrationFile, EveryConfigCalibrationReadsTheSameAfterARewrite) {
  const std::string dir = testing::SourceDir() + "/config/calibration/";
  for (const char* name :
       {"demo_room_camera.yaml", "demo_room_webcam.yaml", "reference_9_region_example.yaml",
        "two_cameras_cam0.yaml", "two_cameras_cam1.yaml"}) {
    SCOPED_TRACE(name);
    Calibration original, back;
    std::string error;
    ASSERT_TRUE(LoadCalibration(dir + name, &original, &error)) << error;
    const std::string text = FormatCalibration(original, std::string("rewritten ") + name);
    ASSERT_TRUE(ParseCalibration(text, name, &back, &error)) << error << "\n" << text;
    EXPECT_EQ(FormatCalibration(back, ""), FormatCalibration(original, ""));
    EXPECT_EQ(back.model, original.model);
    EXPECT_EQ(back.fit_rms_px, original.fit_rms_px) << "4 digits in the files, 4 written";
    EXPECT_EQ(back.pixel_sigma_px, original.pixel_sigma_px);
    double x1, y1, x2, y2;
    ASSERT_TRUE(original.PixelToFloor(700, 400, 0.2, &x1, &y1, &error)) << error;
    ASSERT_TRUE(back.PixelToFloor(700, 400, 0.2, &x2, &y2, &error)) << error;
    EXPECT_EQ(x1, x2);
    EXPECT_EQ(y1, y2);
  }
}

// The layout a person reads: header comments first, vectors on one line,
// the comment that states the pose's convention before its matrix.
TEST(CalibrationFile, WritesTheHeaderThenOneLinePerVector) {
  Calibration c = FullExample();
  c.fit_rms_px = 0.046604;
  const std::string text = FormatCalibration(c, "first line\nsecond line");
  EXPECT_EQ(text.rfind("# first line\n# second line\nfit_rms_px: 0.0466\nmodel: full\n", 0), 0u)
      << text;
  EXPECT_NE(text.find("\n  k: [0.021000000000000001, -0.011299999999999999, "
                      "0.0030999999999999999, -0.00040000000000000002]\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("  position_m: [2, 1.5, 3.1000000000000001]\n# room from camera: p_room = R "
                      "p_camera + position_m\n  rotation_matrix:\n    - ["),
            std::string::npos)
      << text;
}

TEST(CalibrationFile, ReadsARotationVectorAsWellAsAMatrix) {
  // Straight down: a half turn about room x (camera y along room -y).
  const std::string text =
      "model: full\nintrinsics: {width_px: 1920, height_px: 1080, fx_px: 917, fy_px: 917, "
      "cx_px: 960, cy_px: 540, k: [0, 0, 0, 0]}\n"
      "pose: {position_m: [2, 1.5, 3.1], rotation_vector: [3.141592653589793, 0, 0]}\n";
  Calibration c;
  std::string error;
  ASSERT_TRUE(ParseCalibration(text, "mem", &c, &error)) << error;
  double x, y;
  ASSERT_TRUE(c.PixelToFloor(960, 540, 0.0, &x, &y, &error)) << error;
  EXPECT_NEAR(x, 2.0, kRoundTripM);
  EXPECT_NEAR(y, 1.5, kRoundTripM);
}

TEST(CalibrationFile, RegionTableInCentimetresIsTheSameAsInMetres) {
  Calibration cm, m;
  std::string error;
  ASSERT_TRUE(ParseCalibration(RegionsText("cm", 4.0, 60.0), "cm", &cm, &error)) << error;
  ASSERT_TRUE(ParseCalibration(RegionsText("m", 400.0, 0.6), "m", &m, &error)) << error;
  EXPECT_DOUBLE_EQ(cm.regions.regions[4].x.c_px_per_m, 400.0);
  EXPECT_DOUBLE_EQ(cm.regions.regions[4].x.os2_m, 0.6);
  EXPECT_DOUBLE_EQ(cm.regions.regions[4].y.c_px_per_m, -400.0);
  EXPECT_DOUBLE_EQ(cm.regions.regions[4].y.os2_m, 2.5);
  EXPECT_DOUBLE_EQ(m.regions.regions[4].y.os2_m, 250.0);  // -4 and 250 read as metres here
  // u 720: x = (720 - 320) / 400 + 0.6 = 1.6 m.
  double x, y;
  ASSERT_TRUE(cm.PixelToFloor(720, 180, 0.2, &x, &y, &error)) << error;
  EXPECT_DOUBLE_EQ(x, 1.6);
  EXPECT_DOUBLE_EQ(y, 2.5);
  // Written back in metres, read again the same.
  Calibration again;
  ASSERT_TRUE(ParseCalibration(FormatCalibration(cm, ""), "again", &again, &error)) << error;
  EXPECT_DOUBLE_EQ(again.regions.regions[8].x.c_px_per_m, 400.0);
  EXPECT_FALSE(cm.PixelToFloor(720, 180, 0.0, &x, &y, &error));
}

TEST(CalibrationFile, StatesItsPixelErrorAndRefusesANonPositiveOne) {
  Calibration c = FullExample();
  c.pixel_sigma_px = 0.0386;
  Calibration back;
  std::string error;
  ASSERT_TRUE(ParseCalibration(FormatCalibration(c, ""), "mem", &back, &error)) << error;
  EXPECT_DOUBLE_EQ(back.pixel_sigma_px, 0.0386);
  ASSERT_TRUE(ParseCalibration(FormatCalibration(FullExample(), ""), "mem", &back, &error));
  EXPECT_LT(back.pixel_sigma_px, 0.0);  // not stated
  EXPECT_FALSE(ParseCalibration(FormatCalibration(FullExample(), "") + "pixel_sigma_px: 0\n",
                                "cal.yaml", &back, &error));
  EXPECT_NE(error.find("pixel_sigma_px"), std::string::npos) << error;
}

TEST(CalibrationFile, StatesEachRobotsOwnPixelErrorBesideTheFits) {
  Calibration c = FullExample();
  c.pixel_sigma_px = 0.0351;
  c.robot_pixel_sigma_px = {{1, 0.04}, {4, 0.1017}};
  Calibration back;
  std::string error;
  ASSERT_TRUE(ParseCalibration(FormatCalibration(c, ""), "mem", &back, &error)) << error;
  EXPECT_EQ(back.robot_pixel_sigma_px, c.robot_pixel_sigma_px);
  // A listed robot gets its own figure, any other the fit's.
  EXPECT_DOUBLE_EQ(back.PixelSigmaFor(4), 0.1017);
  EXPECT_DOUBLE_EQ(back.PixelSigmaFor(2), 0.0351);
  // Refused, naming the key: a figure that is not positive, a robot id that
  // is not a whole number, a list instead of a map, not a number.
  const std::string base = FormatCalibration(FullExample(), "");
  for (const std::string& bad : {std::string("robot_pixel_sigma_px: {1: 0}\n"),
                                 std::string("robot_pixel_sigma_px: {a: 0.1}\n"),
                                 std::string("robot_pixel_sigma_px: [0.1]\n"),
                                 std::string("robot_pixel_sigma_px: {1: .nan}\n")}) {
    EXPECT_FALSE(ParseCalibration(base + bad, "cal.yaml", &back, &error)) << bad;
    EXPECT_NE(error.find("robot_pixel_sigma_px"), std::string::npos) << bad << ": " << error;
  }
  // The same robot twice: the file's duplicated key, refused by the reader.
  EXPECT_FALSE(ParseCalibration(base + "robot_pixel_sigma_px: {1: 0.1, 1: 0.2}\n", "cal.yaml",
                                &back, &error));
  EXPECT_NE(error.find("duplicated key '1'"), std::string::npos) << error;
}

TEST(PixelSigmaFromFit, AddsTheFitsLostDegreesOfFreedomAndItsOwnPredictionError) {
  // The demo's calibration: 35 points, 11 parameters, 0.0466 px RMS.
  // sigma^2 = 0.0466^2 * 35 / 59 = 0.0012882; times (1 + 11 / 70).
  EXPECT_NEAR(PixelSigmaFromFit(0.0466, 35, 11), 0.038609, kWorkedFigurePx);
  // Many points: the per-axis share of the residual norm, 1 / sqrt(2).
  EXPECT_NEAR(PixelSigmaFromFit(1.0, 100000, 11), std::sqrt(0.5), kLargeSampleLimitPx);
  EXPECT_LT(PixelSigmaFromFit(0.1, 5, 11), 0.0);  // 10 residuals, 11 parameters
}

TEST(CalibrationFile, ErrorsNameTheFileTheLineAndTheKey) {
  Calibration c;
  std::string error;
  const std::string full = FormatCalibration(FullExample(), "");

  EXPECT_FALSE(ParseCalibration("model: pinhole\n", "cal.yaml", &c, &error));
  EXPECT_EQ(error, "cal.yaml:1: model: expected full or regions, got 'pinhole'");

  EXPECT_FALSE(ParseCalibration(full + "extra: 1\n", "cal.yaml", &c, &error));
  EXPECT_EQ(error, "cal.yaml:17: extra: unknown key");

  std::string bent = full;
  bent.replace(bent.find("rotation_matrix:\n    - [") + 24, 1, "7");
  EXPECT_FALSE(ParseCalibration(bent, "cal.yaml", &c, &error));
  EXPECT_EQ(error,
            "cal.yaml:14: pose.rotation_matrix: not a rotation (R^T R must be the identity and "
            "det R = +1, to 1e-6)");

  std::string no_fx = full;
  no_fx.erase(no_fx.find("  fx_px:"), no_fx.find("  fy_px:") - no_fx.find("  fx_px:"));
  EXPECT_FALSE(ParseCalibration(no_fx, "cal.yaml", &c, &error));
  EXPECT_EQ(error, "cal.yaml:3: intrinsics.fx_px: missing key");

  std::string eight = RegionsText("m", 400, 0.6);
  eight.erase(eight.rfind("  - {row: 2"));
  EXPECT_FALSE(ParseCalibration(eight, "r.yaml", &c, &error));
  EXPECT_EQ(error, "r.yaml:7: regions: expected a list of 9 regions (3 rows x 3 columns)");

  std::string zero = RegionsText("m", 0.0, 0.6);
  EXPECT_FALSE(ParseCalibration(zero, "r.yaml", &c, &error));
  EXPECT_EQ(error, "r.yaml:7: regions[0].x.C_calib: must not be zero");

  EXPECT_FALSE(ParseCalibration("model: [full\n", "bad.yaml", &c, &error));
  EXPECT_EQ(error.rfind("bad.yaml:", 0), 0u) << error;
  EXPECT_FALSE(LoadCalibration("/nonexistent/cal.yaml", &c, &error));
  EXPECT_EQ(error, "/nonexistent/cal.yaml: cannot open: No such file or directory");
}

}  // namespace
}  // namespace roomfix::calib
