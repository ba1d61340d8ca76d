// camera_proc as a process, over LCM's UDP multicast in a private network
// namespace: frames from a folder written by the synthetic camera (with a
// truncated and an empty file among them), a webcam that is not there, and
// the live synthetic camera against roomfix_sim's ground truth.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "core/analysis/track_error.h"
#include "msgio/bus.h"
#include "msgio/process.h"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_images.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;
using testing::SourceDir;

constexpr int64_t kStartUtime = 1'700'000'000'000'000;
// The camera issue's target was 5 mm; each bound here is what its test
// measures (printed by it) with a named margin, so a regression shows.
// A folder of rendered frames read from files: deterministic (fixed scene,
// noise seed and start time), measured 0.25 mm in five runs; 1.5x for
// another compiler's or libjpeg's rounding.
constexpr double kFolderRmseM = 0.00025 * 1.5;
// The live synthetic camera (sim:reference_circle, real time, its t = 0
// from roomfix_sim's heartbeat): measured 0.19 to 0.20 mm in five runs on a
// shared 2-core machine (load 3 to 13); 2x for the frames a busier machine
// skips and a heartbeat heard late.
constexpr double kLiveRmseM = 0.00020 * 2.0;
// The simulated webcam of sim_demo.pmd (the robot leans and rocks, 1.9 mm
// per axis): measured 2.32 to 2.43 mm in five runs; 1.5x as above, still a
// sixth of the 23 mm that the nominal lens's calibration gave (issue #32).
constexpr double kWebcamRmseM = 0.00243 * 1.5;
// Peak memory of any child in the oversize-image test: a 1920 x 1080 camera
// pipeline needs well under this; one decode of the 20000 x 20000 PNG would
// need 1200 MB.
constexpr double kMaxChildPeakRssMb = 600.0;

// The demo site with its camera stated as an ideal one (readout_s,
// exposure_s and timestamp_latency_s 0) in `dir`: a folder of frames that
// `roomfix render-camera --scenario lighting` wrote is a global shutter
// stamped exactly, but camera_proc cannot know that of files and takes the
// site's word (the demo site's camera states the webcam's timing).
std::string IdealCameraSite(const testing::TempDir& dir) {
  std::string text = testing::ReadFile(DemoSitePath());
  auto replace_first = [&text](const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
  };
  // The cameras[] entry comes before simulation.webcam's keys.
  replace_first("readout_s: 0.030", "readout_s: 0.0");
  replace_first("exposure_s: 0.0156", "exposure_s: 0.0");
  replace_first("timestamp_latency_s: 0.005", "timestamp_latency_s: 0.0");
  replace_first("calibration: ../calibration/",
                "calibration: " + SourceDir() + "/config/calibration/");
  const std::string path = dir.File("ideal_camera_site.yaml");
  std::ofstream(path) << text;
  return path;
}

int64_t Counter(const std::vector<counter_t>& counters, const std::string& name) {
  for (const counter_t& c : counters) {
    if (c.name == name) return c.count;
  }
  return 0;
}

// truth.csv of render-camera: frame -> (x, y) of the robot's position marker.
std::map<int64_t, std::pair<double, double>> ReadTruth(const std::string& path) {
  std::map<int64_t, std::pair<double, double>> truth;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    if (cells.size() < 8 || cells[5] != "position") continue;
    truth[std::stoll(cells[0])] = {std::stod(cells[6]), std::stod(cells[7])};
  }
  return truth;
}

// The words of command `name`'s exec in a bot-procman file, as the deputy
// runs it: split at spaces (roomfix's .pmd files quote nothing inside an
// exec), ${NAME} replaced from `variables`, the program taken from BinDir()
// (the deputy finds it on its PATH).
std::vector<std::string> PmdCommand(const std::string& pmd_path, const std::string& name,
                                    const std::map<std::string, std::string>& variables) {
  const std::string text = testing::ReadFile(pmd_path);
  const size_t cmd = text.find("cmd \"" + name + "\"");
  const size_t exec = text.find("exec = \"", cmd);
  EXPECT_NE(cmd, std::string::npos) << name << " in " << pmd_path;
  if (cmd == std::string::npos || exec == std::string::npos) return {};
  const size_t begin = exec + 8;
  std::string line = text.substr(begin, text.find('"', begin) - begin);
  for (const auto& [variable, value] : variables) {
    const std::string token = "${" + variable + "}";
    for (size_t at = line.find(token); at != std::string::npos; at = line.find(token, at)) {
      line.replace(at, token.size(), value);
    }
  }
  std::vector<std::string> words;
  std::istringstream in(line);
  for (std::string word; in >> word;) words.push_back(word);
  if (!words.empty()) words[0] = BinDir() + "/" + words[0];
  return words;
}

class CameraProcess : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    bus_ = LcmBus::Create(kDefaultLcmUrl, &error);
    ASSERT_NE(bus_, nullptr) << error;
    bus_->Subscribe<pose2d_t>(
        "POSE_CAMERA", [this](const pose2d_t& p, const MessageInfo&) { poses_.push_back(p); });
    bus_->Subscribe<pose2d_t>("POSE_GROUND_TRUTH", [this](const pose2d_t& p, const MessageInfo&) {
      truth_.push_back(p);
    });
    bus_->Subscribe<marker_pixels_t>(
        "MARKER_PIXELS",
        [this](const marker_pixels_t& m, const MessageInfo&) { pixels_.push_back(m); });
    bus_->Subscribe<process_status_t>("STATUS",
                                      [this](const process_status_t& s, const MessageInfo&) {
                                        if (s.process == "camera_proc") status_.push_back(s);
                                      });
  }

  std::unique_ptr<LcmBus> bus_;
  std::vector<pose2d_t> poses_;
  std::vector<pose2d_t> truth_;
  std::vector<marker_pixels_t> pixels_;
  std::vector<process_status_t> status_;
  testing::TempDir dir_;
};

TEST_F(CameraProcess, AFolderOfFramesBecomesPosesAndBadFilesAreCounted) {
  const std::string frames = dir_.File("frames");
  ChildProcess render({BinDir() + "/roomfix", "render-camera", "--site", DemoSitePath(),
                       "--scenario", "lighting", "--duration", "2", "--out", frames},
                      dir_.File("render.out"));
  ASSERT_EQ(render.Wait(60), 0) << testing::ReadFile(dir_.File("render.out"));
  const auto truth = ReadTruth(frames + "/truth.csv");
  ASSERT_EQ(truth.size(), 60u);
  std::rename((frames + "/truth.csv").c_str(), dir_.File("truth.csv").c_str());
  // Sorted last, so the good frames keep their numbers: half a JPEG and an
  // empty file, as a camera that died mid-write would leave.
  {
    const std::string jpeg = testing::ReadFile(frames + "/frame_000010.jpg");
    std::ofstream(frames + "/zz_truncated.jpg") << jpeg.substr(0, jpeg.size() / 2);
    std::ofstream(frames + "/zz_empty.jpg");
  }
  ChildProcess camera({BinDir() + "/camera_proc", "--config", IdealCameraSite(dir_), "--device",
                       frames, "--start-utime", std::to_string(kStartUtime), "--log-level",
                       "warn"});
  ASSERT_TRUE(HandleUntil(
      bus_.get(),
      [&] {
        return !status_.empty() && Counter(status_.back().rejected, "empty_frame") == 1 &&
               pixels_.size() == 60;
      },
      30))
      << pixels_.size() << " frames";
  EXPECT_EQ(camera.Wait(10), 0) << "camera_proc ends at the end of the folder";
  EXPECT_EQ(Counter(status_.back().rejected, "truncated_frame"), 1);
  EXPECT_EQ(status_.back().dropped, 0);
  ASSERT_EQ(poses_.size(), 60u);
  double sum2 = 0.0;
  for (const pose2d_t& p : poses_) {
    ASSERT_EQ(p.status, pose2d_t::STATUS_OK) << p.measurement_seq;
    EXPECT_EQ(p.utime, kStartUtime + std::llround(p.measurement_seq * 1e6 / 30.0));
    const auto& [x, y] = truth.at(p.measurement_seq);
    sum2 += std::pow(p.x_m - x, 2) + std::pow(p.y_m - y, 2);
  }
  const double rmse = std::sqrt(sum2 / poses_.size());
  std::printf("folder of 60 frames under changing light: %.2f mm RMS\n", rmse * 1e3);
  EXPECT_LT(rmse, kFolderRmseM);
}

// Issue #15: a 57-byte PNG whose header claims 100000 x 100000 px killed
// camera_proc (SIGABRT from OpenCV), and a 20000 x 20000 PNG of a few
// hundred KB would decode to 1.2 GB. Both are refused from their headers and
// counted as wrong_frame_size; the good frames around them still become poses.
TEST_F(CameraProcess, ForgedAndHugeImagesAreCountedAsWrongSizeAndNeverDecoded) {
  const std::string frames = dir_.File("frames");
  ChildProcess render({BinDir() + "/roomfix", "render-camera", "--site", DemoSitePath(),
                       "--scenario", "lighting", "--duration", "0.5", "--out", frames},
                      dir_.File("render.out"));
  ASSERT_EQ(render.Wait(60), 0) << testing::ReadFile(dir_.File("render.out"));
  std::rename((frames + "/truth.csv").c_str(), dir_.File("truth.csv").c_str());
  const std::vector<uint8_t> forged = testing::ForgedPngHeader(100000, 100000);
  ASSERT_EQ(forged.size(), 57u);
  std::ofstream(frames + "/frame_000003_forged.png", std::ios::binary)
      .write(reinterpret_cast<const char*>(forged.data()), 57);
  ASSERT_TRUE(testing::WriteOneColourPng(frames + "/frame_000007_huge.png", 20000, 20000));
  ChildProcess camera({BinDir() + "/camera_proc", "--config", DemoSitePath(), "--device", frames,
                       "--start-utime", std::to_string(kStartUtime), "--log-level", "error"});
  ASSERT_TRUE(HandleUntil(
      bus_.get(),
      [&] {
        return !status_.empty() && Counter(status_.back().rejected, "wrong_frame_size") == 2 &&
               pixels_.size() == 15;
      },
      30))
      << pixels_.size() << " frames, "
      << (status_.empty() ? -1 : Counter(status_.back().rejected, "wrong_frame_size"))
      << " wrong_frame_size";
  EXPECT_EQ(camera.Wait(10), 0) << "camera_proc ends at the end of the folder, not by a signal";
  EXPECT_EQ(Counter(status_.back().rejected, "unreadable_frame"), 0);
  EXPECT_EQ(poses_.size(), 15u);
  // The largest child so far (render-camera or camera_proc): far below the
  // 1.2 GB one decode of the huge PNG would take.
  rusage usage{};
  getrusage(RUSAGE_CHILDREN, &usage);
  std::printf("largest child peak RSS: %.0f MB\n", usage.ru_maxrss / 1024.0);
  EXPECT_LT(usage.ru_maxrss / 1024.0, kMaxChildPeakRssMb);
}

TEST_F(CameraProcess, AMissingWebcamIsRetriedAndReported) {
  ChildProcess camera({BinDir() + "/camera_proc", "--config", DemoSitePath(), "--device",
                       "/dev/video99", "--reopen-max", "0.5", "--log-level", "error"});
  ASSERT_TRUE(HandleUntil(
      bus_.get(),
      [&] {
        return !status_.empty() && status_.back().state == process_status_t::STATE_DEGRADED &&
               Counter(status_.back().counters, "source_lost") >= 3;
      },
      10));
  EXPECT_NE(status_.back().last_error.find("/dev/video99"), std::string::npos)
      << status_.back().last_error;
  camera.Signal(SIGTERM);
  EXPECT_EQ(camera.Wait(5), 0);
}

TEST_F(CameraProcess, TheLiveSyntheticCameraAgreesWithTheSimulatorsGroundTruth) {
  // Started separately, as bot-procman would start them, with no shared
  // flag: camera_proc takes t = 0 from roomfix_sim's heartbeat, so it
  // renders the robot where roomfix_sim says it is, at the capture time.
  ChildProcess sim({BinDir() + "/roomfix_sim", "--config", DemoSitePath(), "--log-level", "warn"});
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  ChildProcess camera({BinDir() + "/camera_proc", "--config", DemoSitePath(), "--device",
                       "sim:reference_circle", "--log-level", "warn"});
  ASSERT_TRUE(HandleUntil(
      bus_.get(), [&] { return poses_.size() >= 60; }, 30));
  const double span_s = (poses_.back().utime - poses_.front().utime) * 1e-6;
  const double rate_hz = (poses_.size() - 1) / span_s;
  // The ground truth (published at its own rate) interpolated to each frame.
  std::vector<analysis::TimedPosition> estimates, reference;
  for (const pose2d_t& p : poses_) estimates.push_back({p.utime, p.x_m, p.y_m});
  for (const pose2d_t& p : truth_) reference.push_back({p.utime, p.x_m, p.y_m});
  const analysis::ErrorSummary e = analysis::CompareToReference(estimates, reference, 200'000);
  const int n = e.compared;
  ASSERT_GT(n, 30);
  const double rmse = e.rmse_m;
  std::printf("live synthetic camera: %zu poses at %.1f Hz, %.2f mm RMS against ground truth\n",
              poses_.size(), rate_hz, rmse * 1e3);
  EXPECT_LT(rmse, kLiveRmseM);
  // 30 fps on a quiet machine; a loaded 2-core CI machine drops some.
  EXPECT_GT(rate_hz, 10.0);
  camera.Signal(SIGINT);
  sim.Signal(SIGINT);
  EXPECT_EQ(camera.Wait(5), 0);
}

// Issue #32: under bot-procman (config/procman/sim_demo.pmd) the synthetic
// webcam was 2.3 cm off roomfix_sim's ground truth, a constant offset, while
// make demo gave 3 mm. Not the clock handshake (t = 0 from the heartbeat
// agrees to the frame): the site's device, sim:webcam, renders through the
// webcam's own lens (principal point 6, -4 px off the nominal, k1 0.03),
// and the .pmd gave camera_proc the site's calibration of the nominal lens:
// 7.2 px at 3.2 mm/px. scripts/demo.sh passed demo_room_webcam.yaml and
// --start-utime, so it never ran this pair. Here both commands run as the
// .pmd spells them, started separately with no shared flag.
TEST_F(CameraProcess, TheSimDemoPmdsCameraAgreesWithItsSimulatorsGroundTruth) {
  const std::map<std::string, std::string> variables = {{"ROOMFIX_HOME", SourceDir()},
                                                        {"ROOMFIX_RUN_DIR", dir_.path()}};
  const std::string pmd = SourceDir() + "/config/procman/sim_demo.pmd";
  const std::vector<std::string> sim_argv = PmdCommand(pmd, "roomfix_sim", variables);
  const std::vector<std::string> camera_argv = PmdCommand(pmd, "camera_proc", variables);
  ASSERT_FALSE(sim_argv.empty());
  ASSERT_FALSE(camera_argv.empty());
  for (const std::string& word : camera_argv) ASSERT_NE(word, "--start-utime");
  // The deputy starts the world's group together: camera_proc first here,
  // so it must wait for the heartbeat (roomfix_sim's first STATUS after 1 s).
  ChildProcess camera(camera_argv, dir_.File("camera_proc.out"));
  ChildProcess sim(sim_argv, dir_.File("roomfix_sim.out"));
  // 90 poses: 3 s of the circle at 30 fps, or longer on a loaded machine.
  constexpr size_t kPoses = 90;
  ASSERT_TRUE(HandleUntil(
      bus_.get(), [&] { return poses_.size() >= kPoses; }, 60))
      << poses_.size()
      << " poses; camera_proc: " << testing::ReadFile(dir_.File("camera_proc.out"));
  std::vector<analysis::TimedPosition> estimates, reference;
  for (const pose2d_t& p : poses_) estimates.push_back({p.utime, p.x_m, p.y_m});
  for (const pose2d_t& p : truth_) reference.push_back({p.utime, p.x_m, p.y_m});
  const analysis::ErrorSummary e = analysis::CompareToReference(estimates, reference, 200'000);
  ASSERT_GT(e.compared, static_cast<int>(kPoses / 2));
  std::printf(
      "sim_demo.pmd's camera_proc and roomfix_sim: %d poses, %.2f mm RMS, %.2f mm max "
      "against ground truth\n",
      e.compared, e.rmse_m * 1e3, e.max_m * 1e3);
  // make demo's figure for the webcam on the circle is 3.0 mm (the robot's
  // lean and rocking, README); here 3 s of it.
  EXPECT_LT(e.rmse_m, kWebcamRmseM);
  camera.Signal(SIGINT);
  sim.Signal(SIGINT);
  EXPECT_EQ(camera.Wait(10), 0);
  EXPECT_EQ(sim.Wait(10), 0);
}

}  // namespace
}  // namespace roomfix
