// roomfix detect: what camera_proc's detector sees in a saved frame (the
// CAMERA_DETECTOR_VIEW overlay, core/vision/detector_view.h), so a lab can
// debug its colours and marker sizes from one image.
#include <CLI/CLI.hpp>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>
#include <vector>

#include "camera_io/image_file.h"
#include "camera_proc/camera_node.h"
#include "core/calib/calibration_file.h"
#include "core/vision/detector_view.h"
#include "core/world/site.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

constexpr char kName[] = "roomfix detect: ";

struct DetectOptions {
  std::string image;
  std::string site;
  std::optional<int> camera_id;
  std::string calibration;
  std::string out;
  std::string lighting = "adaptive";
  std::vector<int> region;  // u, v, width, height (full-resolution px)
  int scale = 1;
  bool json = false;
};

// The lens camera_proc would size the markers with: the calibration (the
// flag's, else the site camera's) when it is a full model, else the nominal
// lens. A calibration that cannot be read is an error only when asked for
// by the flag; the site's own is then a warning (the sizes are nominal).
bool ChooseLens(const DetectOptions& f, const Camera& camera, calib::CameraModel* lens) {
  *lens = calib::NominalCamera(camera.mount_position_m, camera.field_of_view_deg, camera.width_px,
                               camera.height_px);
  const std::string& path = f.calibration.empty() ? camera.calibration_file : f.calibration;
  if (path.empty()) return true;
  calib::Calibration cal;
  std::string error;
  if (!calib::LoadCalibration(path, &cal, &error)) {
    if (!f.calibration.empty()) {
      std::cerr << kName << error << "\n";
      return false;
    }
    std::cerr << kName << "warning: " << error << "; marker sizes from the nominal lens\n";
    return true;
  }
  if (cal.model == calib::Calibration::Model::kFull) *lens = cal.camera;
  return true;
}

bool ParseLighting(const std::string& name, vision::LightingMode* mode) {
  if (name == "fixed") *mode = vision::LightingMode::kFixed;
  if (name == "normalised") *mode = vision::LightingMode::kNormalised;
  if (name == "adaptive") *mode = vision::LightingMode::kAdaptive;
  return name == "fixed" || name == "normalised" || name == "adaptive";
}

nlohmann::ordered_json ToJson(const vision::DetectorView& view, const CameraSetup& setup,
                              const Camera& camera, const DetectOptions& f) {
  nlohmann::ordered_json robots = nlohmann::ordered_json::array();
  for (const vision::RobotDiagnosis& d : view.robots) {
    robots.push_back(
        {{"robot_id", d.robot_id},
         {"reason", vision::RobotViewReasonName(d.reason)},
         {"colour_class", d.class_index >= 0 ? setup.classes[d.class_index].name : std::string()},
         {"value", d.value},
         {"limit", d.limit},
         {"text", d.text}});
  }
  nlohmann::ordered_json blobs = nlohmann::ordered_json::array();
  for (const vision::Blob& b : view.blobs) {
    blobs.push_back({{"colour_class", setup.classes[b.class_index].name},
                     {"u_px", b.u_px},
                     {"v_px", b.v_px},
                     {"area_px", b.area_px},
                     {"circularity", b.circularity}});
  }
  nlohmann::ordered_json rejected = nlohmann::ordered_json::array();
  for (const vision::RejectedBlob& r : view.diagnostics.rejected) {
    rejected.push_back({{"colour_class", setup.classes[r.class_index].name},
                        {"reason", vision::BlobRejectName(r.reason)},
                        {"u_px", r.u_px},
                        {"v_px", r.v_px},
                        {"area_px", r.area_px},
                        {"circularity", r.circularity}});
  }
  return {{"image", f.image},
          {"camera_id", camera.id},
          {"overlay", f.out},
          {"robots", robots},
          {"blobs", blobs},
          {"rejected", rejected},
          {"rejected_not_listed", view.diagnostics.rejected_not_listed}};
}

int RunDetect(const DetectOptions& f) {
  Site site;
  std::string error;
  if (!LoadSite(f.site, &site, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  const Camera* camera = f.camera_id ? site.FindCamera(*f.camera_id) : site.FindCameraOrFirst(-1);
  if (camera == nullptr) {
    std::cerr << kName << f.site << ": no camera"
              << (f.camera_id ? " with id " + std::to_string(*f.camera_id) : std::string()) << "\n";
    return 1;
  }
  cv::Mat frame;
  // Bounded by the camera's size before decoding (a hostile header), then
  // exactly its size: a frame of another camera would give wrong areas.
  if (!camera::ReadImageChecked(f.image, camera->width_px, camera->height_px, cv::IMREAD_COLOR,
                                &frame, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  if (frame.cols != camera->width_px || frame.rows != camera->height_px) {
    std::cerr << kName << f.image << " is " << frame.cols << "x" << frame.rows << " px; camera "
              << camera->id << " of " << f.site << " takes " << camera->width_px << "x"
              << camera->height_px << "\n";
    return 1;
  }
  cv::Rect region(0, 0, frame.cols, frame.rows);
  if (!f.region.empty()) {
    region = cv::Rect(f.region[0], f.region[1], f.region[2], f.region[3]);
    if (region.width <= 0 || region.height <= 0 ||
        (region & cv::Rect(0, 0, frame.cols, frame.rows)) != region) {
      std::cerr << kName << "--region " << region.width << "x" << region.height << " at ("
                << region.x << ", " << region.y << ") does not lie within the " << frame.cols << "x"
                << frame.rows << " frame\n";
      return 1;
    }
  }
  calib::CameraModel lens;
  if (!ChooseLens(f, *camera, &lens)) return 1;
  CameraNodeOptions node_options;
  if (!ParseLighting(f.lighting, &node_options.lighting)) {
    std::cerr << kName << "--lighting must be fixed, normalised or adaptive\n";
    return 1;
  }
  CameraSetup setup;
  if (!MakeCameraSetup(site.room, *camera, lens, node_options, &setup, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  vision::DetectorOptions detector_options;
  detector_options.lighting = node_options.lighting;
  detector_options.blur_sigma_px = node_options.blur_sigma_px;
  const vision::MarkerDetector detector(setup.classes, detector_options);
  vision::DetectorViewInput in;
  in.region_px = region;
  in.scale = f.scale;
  in.source_size = frame.size();
  in.robots = setup.robots;
  in.tracker = setup.tracker;
  in.list_reasons = true;
  if (f.scale > 1) {
    cv::resize(frame(region), in.bgr, cv::Size(), 1.0 / f.scale, 1.0 / f.scale, cv::INTER_AREA);
  } else {
    in.bgr = frame(region).clone();
  }
  const vision::DetectorView view = vision::RenderDetectorView(detector, in);
  if (!camera::WriteImageChecked(f.out, view.bgr, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  if (f.json) {
    std::cout << ToJson(view, setup, *camera, f).dump(2) << "\n";
    return 0;
  }
  std::cout << "wrote " << f.out << ": camera " << camera->id << ", " << view.blobs.size()
            << " blobs, " << view.diagnostics.rejected.size() << " components dropped\n";
  for (const vision::RobotDiagnosis& d : view.robots) {
    std::cout << "  " << d.text << " [" << vision::RobotViewReasonName(d.reason) << "]\n";
  }
  return 0;
}

}  // namespace

void AddDetectCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "detect",
      "What the camera's detector sees in a saved frame: its class masks and blobs over the "
      "dimmed frame as a PNG, and per robot why it is or is not found (as camera_proc's "
      "CAMERA_DETECTOR_VIEW)");
  auto f = std::make_shared<DetectOptions>();
  cmd->add_option("image", f->image, "A frame of the camera (PNG, JPEG, BMP or PNM)")->required();
  cmd->add_option("--site", f->site, "Site file")->required();
  cmd->add_option("--camera", f->camera_id, "Camera id in the site file (default: the first)");
  cmd->add_option("--out", f->out, "The overlay PNG to write")->required();
  cmd->add_option("--calibration", f->calibration,
                  "Calibration YAML that sizes the markers (default: the site camera's; the "
                  "nominal lens without one)");
  cmd->add_option("--lighting", f->lighting, "fixed, normalised or adaptive (as camera_proc)")
      ->capture_default_str()
      ->check(CLI::IsMember({"fixed", "normalised", "adaptive"}));
  cmd->add_option("--region", f->region, "Only this full-resolution rectangle: U V WIDTH HEIGHT")
      ->expected(4);
  cmd->add_option("--scale", f->scale, "Reduce the view by 1, 2, 4 or 8")
      ->capture_default_str()
      ->check(CLI::IsMember({1, 2, 4, 8}));
  cmd->add_flag("--json", f->json, "Print the robots, blobs and dropped components as JSON");
  cmd->callback([f, exit_code] { *exit_code = RunDetect(*f); });
}

}  // namespace roomfix
