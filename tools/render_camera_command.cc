// roomfix render-camera: synthetic ceiling-camera frames of a site with
// ground truth (sim/synthetic_camera.h).
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>
#include <vector>

#include "camera_io/image_file.h"
#include "core/calib/calibration_file.h"
#include "core/world/file_io.h"
#include "core/world/site.h"
#include "sim/synthetic_camera.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

struct RenderCameraOptions {
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
  bool tripod_robots = false;
};

// The reference's calibration procedure on the synthetic camera: the robot's
// markers on a tripod at every grid point at least one grid step from the
// walls where the camera sees the whole position marker, one image each, and
// points.csv (image,x_m,y_m,height_m) for `roomfix calibrate
// --marker-images`. With --tripod-robots also every robot of the camera at
// the points half a step off that grid (places the fit does not see), each
// at its own heading, and robots.csv (image,x_m,y_m,height_m,robot_id) for
// `roomfix calibrate --robot-images`: each robot's held-out pixel noise.
int WriteTripodImages(const RenderCameraOptions& f, const Site& site, const Camera& camera,
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
  const double step = f.tripod_step_m > 0.0 ? f.tripod_step_m : site.room.grid_m;
  const Room& room = site.room;
  int frame = 0;
  std::string error;
  // One image of `robot` at (x, y, heading) as `stem`.jpg (or .png when
  // lossless); false when the camera does not see its whole position marker
  // (as in a lab, the tripod goes only where the camera sees it: a cut
  // disc's centroid is not the disc's) or the write failed (*error set).
  auto write = [&](const CameraRobot& robot, double x, double y, double heading_rad,
                   const std::string& stem, std::string* name) {
    cv::Mat image;
    std::vector<sim::MarkerTruth> truth;
    synthetic.Render(0.0, frame++, {sim::RobotState{robot.robot_id, x, y, heading_rad}}, &image,
                     &truth);
    if (std::none_of(truth.begin(), truth.end(),
                     [](const sim::MarkerTruth& m) { return !m.is_heading_marker && m.visible; })) {
      return false;
    }
    // As the camera delivers its frames (its JPEG at the device's quality,
    // as camera_proc's sim: source encodes them), so that the fit's residual,
    // and the pixel_sigma_px calibrate derives from it, is the centroid
    // noise the markers will have in operation (docs/camera.md). A lossless
    // image understates it: on the hall's clean camera 0.003 px against
    // about 0.05 px in its JPEG frames.
    std::vector<uint8_t> jpeg;
    if (!synthetic.Encode(image, f.jpeg_quality, &jpeg)) {
      error = stem + ": cannot encode as JPEG";
      return false;
    }
    *name = stem + (jpeg.empty() ? ".png" : ".jpg");
    const std::string path = f.tripod_dir + "/" + *name;
    if (!(jpeg.empty() ? camera::WriteImageChecked(path, image, &error)
                       : WriteOutputFile(path, std::string(jpeg.begin(), jpeg.end()), &error))) {
      return false;
    }
    return true;
  };
  // Every point of the grid through (x0, y0) with this step, inside the
  // room by at least one grid step.
  auto each_point = [&](double offset_m, const std::function<bool(double, double)>& visit) {
    for (double y = room.min_y_m + step + offset_m; y < room.min_y_m + room.size_y_m - 0.5 * step;
         y += step) {
      for (double x = room.min_x_m + step + offset_m; x < room.min_x_m + room.size_x_m - 0.5 * step;
           x += step) {
        if (!visit(x, y)) return false;
      }
    }
    return true;
  };
  const CameraRobot& tripod = camera.robots.front();
  std::ostringstream csv, robots_csv;
  csv << "image,x_m,y_m,height_m\n";
  robots_csv << "image,x_m,y_m,height_m,robot_id\n";
  int n = 0, out_of_view = 0, held_out = 0;
  bool ok = each_point(0.0, [&](double x, double y) {
    const std::string stem = fmt::format("tripod_{:03d}", n);
    std::string name;
    if (!write(tripod, x, y, 0.0, stem, &name)) {
      ++out_of_view;
      return error.empty();
    }
    csv << name << "," << x << "," << y << "," << tripod.marker_height_m << "\n";
    ++n;
    return true;
  });
  if (ok && f.tripod_robots) {
    int point = 0;
    ok = each_point(0.5 * step, [&](double x, double y) {
      for (const CameraRobot& robot : camera.robots) {
        // Headings spread by the golden angle: every robot is seen at many,
        // as it will be while it drives.
        const double heading_rad = std::remainder(2.399963 * (point + robot.robot_id), 2 * M_PI);
        const std::string stem = fmt::format("robot_{}_{:03d}", robot.robot_id, point);
        std::string name;
        if (!write(robot, x, y, heading_rad, stem, &name)) {
          if (!error.empty()) return false;
          continue;
        }
        robots_csv << name << "," << x << "," << y << "," << robot.marker_height_m << ","
                   << robot.robot_id << "\n";
        ++held_out;
      }
      ++point;
      return true;
    });
  }
  if (!ok || !WriteOutputFile(f.tripod_dir + "/points.csv", csv.str(), &error) ||
      (f.tripod_robots &&
       !WriteOutputFile(f.tripod_dir + "/robots.csv", robots_csv.str(), &error))) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  std::cout << "wrote " << n << " tripod images (" << tripod.position_marker << " marker at "
            << tripod.marker_height_m << " m, every " << step << " m) and points.csv to "
            << f.tripod_dir;
  if (out_of_view > 0) std::cout << "; " << out_of_view << " grid points out of the camera's view";
  if (f.tripod_robots) {
    std::cout << "; " << held_out << " images of the camera's " << camera.robots.size()
              << " robots half a step off the grid and robots.csv";
  }
  std::cout << "\n";
  return 0;
}

int RunRenderCamera(const RenderCameraOptions& f) {
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
  auto f = std::make_shared<RenderCameraOptions>();
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
                  "grid point the camera sees, one image each in the camera's JPEG, and "
                  "points.csv for calibrate --marker-images");
  cmd->add_option("--tripod-step", f->tripod_step_m,
                  "Spacing of the tripod points, m (default: the room's grid)");
  cmd->add_flag("--tripod-robots", f->tripod_robots,
                "With --tripod-grid: also every robot of the camera half a step off the grid, "
                "and robots.csv for calibrate --robot-images (each robot's held-out noise)");
  cmd->add_option("--seed", f->seed, "Noise seed")->capture_default_str();
  cmd->add_option("--jpeg-quality", f->jpeg_quality,
                  "JPEG quality of folder frames and tripod images (the webcam scenario uses its "
                  "own; 0: lossless PNG)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100));
  cmd->callback([f, exit_code] { *exit_code = RunRenderCamera(*f); });
}

}  // namespace roomfix
