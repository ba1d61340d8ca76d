#include "viewer/footprint.h"

#include <cmath>
#include <string>

#include "core/calib/calibration_file.h"
#include "core/calib/fisheye_camera.h"

namespace roomfix::viewer {

std::vector<CameraFootprint> CameraFootprints(const Site& site,
                                              const std::map<int, std::string>& calibration_texts,
                                              double height_m) {
  std::vector<CameraFootprint> out;
  for (const Camera& camera : site.cameras) {
    CameraFootprint f;
    f.camera_id = camera.id;
    calib::Calibration calibration;
    std::string error;
    const auto text = calibration_texts.find(camera.id);
    if (text != calibration_texts.end() &&
        calib::ParseCalibration(text->second, camera.calibration_file, &calibration, &error) &&
        calibration.model == calib::Calibration::Model::kFull &&
        calibration.camera.intrinsics.width_px == camera.width_px &&
        calibration.camera.intrinsics.height_px == camera.height_px) {
      f.calibrated = true;
    } else {
      calibration = calib::Calibration{};
      calibration.model = calib::Calibration::Model::kFull;
      calibration.camera = calib::NominalCamera(camera.mount_position_m, camera.field_of_view_deg,
                                                camera.width_px, camera.height_px);
    }
    f.lens_m = {calibration.camera.pose.position_m.x(), calibration.camera.pose.position_m.y()};
    // Clockwise around the image from its top-left corner: top, right,
    // bottom, left edges; pixel centres run 0 .. size - 1.
    const double w = camera.width_px - 1.0, h = camera.height_px - 1.0;
    const double corners[5][2] = {{0, 0}, {w, 0}, {w, h}, {0, h}, {0, 0}};
    for (int side = 0; side < 4; ++side) {
      for (int k = 0; k < kFootprintSamplesPerSide; ++k) {
        const double a = static_cast<double>(k) / kFootprintSamplesPerSide;
        const double u = corners[side][0] + a * (corners[side + 1][0] - corners[side][0]);
        const double v = corners[side][1] + a * (corners[side + 1][1] - corners[side][1]);
        double x = 0, y = 0;
        if (calibration.PixelToFloor(u, v, height_m, &x, &y, &error) && std::isfinite(x) &&
            std::isfinite(y)) {
          f.floor_m.push_back({x, y});
        }
      }
    }
    out.push_back(f);
  }
  return out;
}

double FootprintHeight(const Site& site) {
  for (const Camera& camera : site.cameras) {
    if (!camera.robots.empty()) return camera.robots.front().marker_height_m;
  }
  return 0.0;
}

}  // namespace roomfix::viewer
