#include "core/calib/camera_timing.h"

#include <gtest/gtest.h>

#include <cmath>

namespace roomfix::calib {
namespace {

constexpr int64_t kCapture = 1'700'000'000'000'000;

// A 1080p webcam: 30 ms rolling readout, 20 ms exposure, 50 ms USB latency.
CameraTiming Webcam() {
  CameraTiming t;
  t.readout_s = 0.030;
  t.exposure_s = 0.020;
  t.latency_s = 0.050;
  t.height_px = 1080;
  return t;
}

TEST(CameraTiming, WithoutReadoutExposureOrLatencyEveryRowIsTheCaptureTime) {
  CameraTiming t;
  t.height_px = 1080;
  EXPECT_EQ(RowMidExposureUtime(t, kCapture, 0.0), kCapture);
  EXPECT_EQ(RowMidExposureUtime(t, kCapture, 1079.0), kCapture);
}

TEST(CameraTiming, RowTimeFollowsTheContract) {
  const CameraTiming t = Webcam();
  // Last row: read at the capture time less the latency; mid-exposure 10 ms
  // before that.
  EXPECT_EQ(RowMidExposureUtime(t, kCapture, 1079.0), kCapture - 50'000 - 10'000);
  // First row: 1079 row periods of 30 ms / 1080 earlier still (29972.2 us).
  EXPECT_EQ(RowMidExposureUtime(t, kCapture, 0.0), kCapture - 60'000 - 29'972);
  // A fractional centroid row lies between its neighbours, linearly.
  const int64_t mid = RowMidExposureUtime(t, kCapture, 539.5);
  EXPECT_EQ(mid, kCapture - 60'000 - 14'986);
}

TEST(CameraTiming, RefusesNegativeFiguresAndNoHeight) {
  std::string error;
  CameraTiming t = Webcam();
  EXPECT_TRUE(t.IsValid(&error)) << error;
  t.readout_s = -0.01;
  EXPECT_FALSE(t.IsValid(&error));
  t = Webcam();
  t.height_px = 0;
  EXPECT_FALSE(t.IsValid(&error));
  t = Webcam();
  t.exposure_s = std::nan("");
  EXPECT_FALSE(t.IsValid(&error));
}

// The reason the centroid's row is the marker's time: a disc moving at
// constant velocity, imaged through a rolling shutter (row r sees it at its
// own time), has a coverage centroid that is the disc's centre at the time of
// the centroid's row. Rasterised here with 16 x 16 subsamples per pixel.
TEST(CameraTiming, CentroidRowTimeIsWhenTheDiscWasAtTheCentroid) {
  CameraTiming t;
  t.readout_s = 0.030;
  t.height_px = 1080;
  const double radius_px = 12.0;
  // 20 cm/s at ~3 px/cm straight below the lens: ~60 px/s; try fast diagonal
  // motion (600 px/s) to make the shear large: 18 px over the readout.
  for (const auto& vel : {std::array<double, 2>{600.0, 0.0}, std::array<double, 2>{0.0, 600.0},
                          std::array<double, 2>{-420.0, 420.0}}) {
    // Centre at row time 0 (the first row's read): (300, 500).
    auto centre_at = [&](double time_s, double* u, double* v) {
      *u = 300.0 + vel[0] * time_s;
      *v = 500.0 + vel[1] * time_s;
    };
    const double row_period_s = t.readout_s / t.height_px;
    double sum = 0.0, su = 0.0, sv = 0.0;
    for (int r = 440; r < 560; ++r) {
      for (int c = 240; c < 360; ++c) {
        int inside = 0;
        for (int a = 0; a < 16; ++a) {
          for (int b = 0; b < 16; ++b) {
            // Each sub-row is read at its own time (a continuous readout).
            const double sv_px = r - 0.5 + (a + 0.5) / 16.0;
            const double su_px = c - 0.5 + (b + 0.5) / 16.0;
            double cu = 0, cv = 0;
            centre_at(sv_px * row_period_s, &cu, &cv);
            if (std::hypot(su_px - cu, sv_px - cv) <= radius_px) ++inside;
          }
        }
        const double w = inside / 256.0;
        sum += w;
        su += w * c;
        sv += w * r;
      }
    }
    const double u = su / sum, v = sv / sum;
    // Frame stamped when its last row is read (no latency, no exposure).
    const int64_t capture = kCapture;
    const int64_t row_utime = RowMidExposureUtime(t, capture, v);
    const double row_time_s =
        (static_cast<double>(row_utime - capture) * 1e-6) + (t.height_px - 1) * row_period_s;
    double cu = 0, cv = 0;
    centre_at(row_time_s, &cu, &cv);
    // 16 x 16 subsampling resolves a centroid to ~0.005 px; the microsecond
    // rounding of the time is 0.0006 px at 600 px/s.
    constexpr double kTolPx = 0.01;
    EXPECT_NEAR(u, cu, kTolPx) << vel[0] << "," << vel[1];
    EXPECT_NEAR(v, cv, kTolPx) << vel[0] << "," << vel[1];
  }
}

}  // namespace
}  // namespace roomfix::calib
