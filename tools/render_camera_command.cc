// roomfix render-camera: synthetic ceiling-camera frames of a site with
// ground truth (sim/synthetic_camera.h).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>
#include <vector>

#include "camera_proc/image_file.h"
#include "core/calib/calibration_file.h"
#include "core/world/file_io.h"
#include "core/world/site.h"
#include "sim/synthetic_camera.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

struct RenderCameraFlags {
  std::string site;
  std::optional<int> camera_id;
  std::string scenario;
  double duration_s = 10.0;
  std::optional<double> fps;
  std::string out;
  std::string png;
  double time_s = 0.0;
  std::string calibration;
  uint32_t seed = 1;
  int jpeg_quality = 90;
  std::string tripod_dir;
  double tripod_step_m = 0.0;
};

// The reference's calibration procedure on the synthetic camera: the robot's
// markers on a tripod at every grid point at least one grid step from the
// walls, one image each, and points.csv (image,x_m,y_m,height_m) for
// `roomfix calibrate --marker-images`.
int WriteTripodImages(const RenderCameraFlags& f, const Site& site, const Camera& camera,
                      const sim::SyntheticCamera& synthetic) {
  const char* kName = "roomfix render-camera: ";
  if (camera.robots.empty()) {
    std::cerr << kName << "camera " << camera.id << " has no robot whose marker could be shown\n";
    return 1;
  }
  std::error_code ec;
  std::filesystem::create_directories(f.tripod_dir, ec);
  if (ec) {
    std::cerr << kName << f.tripod_dir << ": cannot make the folder: " << ec.message() << "\n";
    return 1;
  }
  // Written whole after the images, every step checked (file_io.h).
  std::ostringstream csv;
  csv << "image,x_m,y_m,height_m\n";
  const double step = f.tripod_step_m > 0.0 ? f.tripod_step_m : site.room.grid_m;
  const CameraRobot& robot = camera.robots.front();
  const Room& room = site.room;
  int n = 0;
  for (double y = room.min_y_m + step; y < room.min_y_m + room.size_y_m - 0.5 * step; y += step) {
    for (double x = room.min_x_m + step; x < room.min_x_m + room.size_x_m - 0.5 * step; x += step) {
      cv::Mat image;
      synthetic.Render(0.0, n, {sim::RobotState{robot.robot_id, x, y, 0.0}}, &image);
      char name[64];
      std::snprintf(name, sizeof(name), "tripod_%03d.png", n);
      std::string error;
      if (!camera::WriteImageChecked(f.tripod_dir + "/" + name, image, &error)) {
        std::cerr << kName << error << "\n";
        return 1;
      }
      csv << name << "," << x << "," << y << "," << robot.marker_height_m << "\n";
      ++n;
    }
  }
  std::string error;
  if (!WriteOutputFile(f.tripod_dir + "/points.csv", csv.str(), &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  std::cout << "wrote " << n << " tripod images (" << robot.position_marker << " marker at "
            << robot.marker_height_m << " m, every " << step << " m) and points.csv to "
            << f.tripod_dir << "\n";
  return 0;
}

int RunRenderCamera(const RenderCameraFlags& f) {
  const char* kName = "roomfix render-camera: ";
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
  // The scenario: the flag, else the camera's "sim:<scenario>" device, else clean.
  std::string scenario_name = f.scenario;
  if (scenario_name.empty()) {
    scenario_name = camera->device.rfind("sim:", 0) == 0 ? camera->device : "clean";
  }
  sim::SimScenario scenario;
  if (!sim::ParseSimScenario(scenario_name, site, &scenario, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  scenario.seed = f.seed;
  calib::CameraModel model = calib::NominalCamera(
      camera->mount_position_m, camera->field_of_view_deg, camera->width_px, camera->height_px);
  if (!f.calibration.empty()) {
    calib::Calibration cal;
    if (!calib::LoadCalibration(f.calibration, &cal, &error)) {
      std::cerr << kName << error << "\n";
      return 1;
    }
    if (cal.model != calib::Calibration::Model::kFull) {
      std::cerr << kName << f.calibration
                << ": a 9-region calibration cannot render images; give a full model\n";
      return 1;
    }
    if (cal.camera.intrinsics.width_px != camera->width_px ||
        cal.camera.intrinsics.height_px != camera->height_px) {
      std::cerr << kName << f.calibration << ": calibrated for " << cal.camera.intrinsics.width_px
                << "x" << cal.camera.intrinsics.height_px << " px, the camera is "
                << camera->width_px << "x" << camera->height_px << "\n";
      return 1;
    }
    model = cal.camera;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const sim::SyntheticCamera synthetic(site, *camera, model, scenario);
  const double setup_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  if (!f.tripod_dir.empty()) return WriteTripodImages(f, site, *camera, synthetic);
  if (!f.png.empty()) {
    cv::Mat image;
    std::vector<sim::MarkerTruth> truth;
    synthetic.Render(f.time_s, 0, synthetic.SimulatedRobots(f.time_s), &image, &truth);
    if (!camera::WriteImageChecked(f.png, image, &error)) {
      std::cerr << kName << error << "\n";
      return 1;
    }
    std::cout << "wrote " << f.png << ": camera " << camera->id << ", scenario " << scenario.name
              << ", t " << f.time_s << " s, " << image.cols << "x" << image.rows << " px\n";
    for (const auto& m : truth) {
      std::cout << "  " << (m.robot_id < 0 ? "distractor" : "robot " + std::to_string(m.robot_id))
                << " " << m.colour_class << (m.is_heading_marker ? " (heading)" : "") << " at ("
                << m.x_m << ", " << m.y_m << ", " << m.z_m << ") m: centroid (" << m.centroid_u_px
                << ", " << m.centroid_v_px << ") px" << (m.visible ? "" : ", not wholly in view")
                << "\n";
    }
    return 0;
  }
  if (f.out.empty()) {
    std::cerr << kName << "give --out DIR|FILE.avi|FILE.mp4 or --png FRAME.png\n";
    return 1;
  }
  sim::SequenceOptions options;
  options.duration_s = f.duration_s;
  options.fps = f.fps ? *f.fps : (camera->fps > 0 ? camera->fps : 30.0);
  options.jpeg_quality = f.jpeg_quality;
  const auto t1 = std::chrono::steady_clock::now();
  if (!sim::WriteSequence(synthetic, options, f.out, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  const double write_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  const long frames = std::lround(options.duration_s * options.fps);
  std::cout << "wrote " << frames << " frames (" << synthetic.width_px() << "x"
            << synthetic.height_px() << " px, " << options.fps << " fps, scenario " << scenario.name
            << ") to " << f.out << " in " << write_s << " s (set-up " << setup_ms
            << " ms); truth: ";
  const std::string ext = f.out.size() > 4 ? f.out.substr(f.out.size() - 4) : "";
  if (ext == ".avi" || ext == ".mp4") {
    std::cout << f.out.substr(0, f.out.size() - 4) << "_truth.csv\n";
  } else {
    std::cout << f.out << "/truth.csv\n";
  }
  return 0;
}

}  // namespace

void AddRenderCameraCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "render-camera",
      "Render synthetic ceiling-camera frames of a site (floor, grid, robots' markers, lighting, "
      "noise) with ground truth: a sequence (folder of JPEGs or .avi/.mp4, plus truth CSV) or one "
      "PNG");
  auto f = std::make_shared<RenderCameraFlags>();
  cmd->add_option("--site", f->site, "Site file")->required();
  cmd->add_option("--camera", f->camera_id, "Camera id in the site file (default: the first)");
  cmd->add_option("--scenario", f->scenario,
                  "clean, reference_circle, lighting, distractors, harsh or webcam (default: the "
                  "camera's sim: device, else clean)");
  cmd->add_option("--duration", f->duration_s, "Sequence length, seconds")->capture_default_str();
  cmd->add_option("--fps", f->fps, "Frames per second (default: the camera's)");
  cmd->add_option("--out", f->out, "Folder for frame_NNNNNN.jpg, or a .avi/.mp4 video");
  cmd->add_option("--png", f->png, "Write one frame to this PNG instead of a sequence");
  cmd->add_option("--time", f->time_s, "Instant of the --png frame, seconds")
      ->capture_default_str();
  cmd->add_option("--calibration", f->calibration,
                  "Full-model calibration YAML to render through (default: the nominal camera "
                  "from the site's mount position and field of view)");
  cmd->add_option("--tripod-grid", f->tripod_dir,
                  "Write the reference's calibration images instead: the robot's markers at each "
                  "grid point, one PNG each, and points.csv for calibrate --marker-images");
  cmd->add_option("--tripod-step", f->tripod_step_m,
                  "Spacing of the tripod points, m (default: the room's grid)");
  cmd->add_option("--seed", f->seed, "Noise seed")->capture_default_str();
  cmd->add_option("--jpeg-quality", f->jpeg_quality, "JPEG quality of folder frames")
      ->capture_default_str();
  cmd->callback([f, exit_code] { *exit_code = RunRenderCamera(*f); });
}

}  // namespace roomfix
