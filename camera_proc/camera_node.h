#ifndef ROOMFIX_CAMERA_PROC_CAMERA_NODE_H_
#define ROOMFIX_CAMERA_PROC_CAMERA_NODE_H_

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "camera_io/frame_source.h"
#include "core/calib/calibration_file.h"
#include "core/calib/camera_timing.h"
#include "core/vision/marker_detector.h"
#include "core/vision/robot_tracker.h"
#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/channels.h"
#include "msgio/lcm_types_fwd.h"
#include "msgio/messages.h"
#include "msgio/process.h"
#include "msgio/subscriptions.h"

namespace roomfix {

struct CameraNodeOptions {
  vision::LightingMode lighting = vision::LightingMode::kAdaptive;
  // The full-frame search looks at the frame shrunk by this factor (1, 2, 4
  // or 8; a JPEG is decoded at that size by DCT scaling) and then re-measures
  // each blob on a full-resolution window. 2 keeps a 5 cm heading marker
  // 8 px across at the corners of the demo floor.
  int full_search_scale = 2;
  // A robot's top speed on the floor; the tracking window grows with it and
  // with the time since the last find.
  double max_speed_mps = 1.0;
  // One-sigma pixel error per axis for the pose covariance when the
  // calibration does not state its measured pixel_sigma_px (older files,
  // the 9-region model): an assumption, pixels.
  double centroid_sigma_px = 0.1;
  // The centroid's extra sigma along a motion streak, as a fraction of the
  // streak's length (calib/pose_covariance.h); only with the site camera's
  // exposure_s above 0. Fitted on the simulated webcam (docs/camera.md).
  double blur_sigma_fraction = 0.1;
  // The robot's floor velocity for the covariance's motion terms and the
  // heading marker's time shift: from its own poses over this span (s).
  double velocity_span_s = 0.3;
  // Blur of the class masks, full-resolution pixels.
  double blur_sigma_px = 1.0;
  // Remove the centroid's perspective bias (calib/marker_projection.h);
  // full camera model only.
  bool correct_disc_centroid = true;
  // Robots out of view (never found, or lost) are looked for by a
  // full-frame search once in this many frames
  // (vision::TrackerOptions::absent_search_period_frames: a robot entering
  // the view is acquired within this many frames). 1: every frame.
  int absent_search_period_frames = 4;
  // A frame with more blobs than this identifies no robot
  // (vision::TrackerOptions::max_blobs; STATUS too_many_blobs per
  // robot-frame).
  int max_blobs_per_frame = 512;
  // A marker cut by the image's edge never identifies a robot nor gives it
  // a pose (vision::TrackerOptions::clip_radius_factor). False only to
  // measure what that prevents (tests, benchmarks).
  bool refuse_clipped_markers = true;
  // Search the full frame in every frame, as the reference did (for the
  // benchmark and for comparison; never needed in operation).
  bool always_full_search = false;
  // Poses on these channels (the ultrasound, the fused track) tell the
  // tracker roughly where a robot is, so a start-up with a look-alike in view
  // resolves itself; empty: none.
  std::vector<std::string> hint_channels = {kUltrasoundPoseChannel};
  // The hint's radius: 3 sigma of its covariance, at least this (m).
  double hint_min_radius_m = 0.15;
  double hint_max_radius_m = 0.5;
  // A reduced JPEG of a frame on CAMERA_PREVIEW this often, for the viewer
  // (0: never). Costs one 1/8-size decode and a small encode.
  double preview_hz = 1.0;
  // What the detector sees (CAMERA_DETECTOR_VIEW, core/vision/detector_view.h)
  // of the whole frame this often without being asked (0: only on request,
  // CAMERA_DETECTOR_VIEW_REQUEST). Costs a reduced decode, a detection with
  // its masks and a PNG encode per view; nothing per frame while off.
  double detector_view_hz = 0.0;
  // The most views per second a request may ask for (a faster one is slowed
  // to this), and the longest it may last.
  double detector_view_max_hz = 2.0;
  double detector_view_max_duration_s = 600.0;
  // A view is reduced (by 1, 2, 4 or 8) until it is at most this wide.
  int detector_view_max_width_px = 960;
  // The frame source's own exposure and timestamp timing when the device
  // defines it (FrameSource::device_timing: a synthetic scenario renders its
  // own physics, so its figures are the truth whatever the site says); empty:
  // the site camera's readout_s, exposure_s and timestamp_latency_s, the only
  // statement there is of a real camera's timing.
  std::optional<calib::CameraTiming> device_timing;
  // Measures processing time (microseconds, any monotonic epoch).
  std::function<int64_t()> steady_clock;

  bool IsValid(std::string* error) const;
};

// What the node derives from the site's camera entry: the detector's classes
// and the tracker's robots, sized from the lens (the calibration when there
// is one, else the nominal lens at the mount position).
struct CameraSetup {
  std::vector<vision::ColourClass> classes;
  std::vector<vision::TrackedRobotSpec> robots;
  vision::TrackerOptions tracker;
  // Per tracked robot: marker height, and the two markers' radii (m).
  std::vector<double> marker_height_m;
  std::vector<double> position_radius_m;
  std::vector<double> heading_radius_m;
};
bool MakeCameraSetup(const Room& room, const Camera& camera, const calib::CameraModel& lens,
                     const CameraNodeOptions& options, CameraSetup* setup, std::string* error);

// camera_proc's logic with no camera and no clock of its own: frames come in
// with their capture time; per frame the node asks the tracker where to
// look, decodes only that (a reduced-size view for a full-frame search,
// full-resolution windows while tracking), detects, tracks, and publishes
// MARKER_PIXELS (every processed frame, found or not) and, with a
// calibration, POSE_CAMERA per robot (lost when not seen). Unreadable frames
// are counted by reason (corrupt_frame, empty_frame) and skipped; gaps in
// the frame sequence are counted as dropped frames.
class CameraNode {
 public:
  // `calibration` may be empty: then only MARKER_PIXELS is published.
  CameraNode(const Site& site, const Camera& camera, std::optional<calib::Calibration> calibration,
             Bus* bus, const CameraNodeOptions& options, int64_t start_utime);

  // False (with the reason in *error) when the site's camera cannot be
  // tracked (no classes, a robot naming an unknown class).
  bool ok(std::string* error) const;

  void OnFrame(camera::Frame* frame, int64_t now_utime);
  // The stages after detection for a recorded MARKER_PIXELS of this camera
  // (the detector's output as OnFrame published it): tracking, pixel to
  // floor with the calibration, covariance, POSE_CAMERA. OnFrame runs the
  // same code (Track, PublishPoses) on the blobs it detected, so a replay of
  // a log's pixels gives the live poses. Time is the message's: the frame's
  // capture utime, the pose latency its processing_time_us. Nothing is
  // published on MARKER_PIXELS. Pixels of another camera are ignored;
  // counted: wrong_frame_size, unknown_marker_class, non_finite_marker
  // (rejections; the frame's other markers are used),
  // search_mode_differs (this tracker planned another search than the live
  // one), capped_frames (the message held the wire cap's number of markers).
  void OnMarkerPixels(const marker_pixels_t& msg, int64_t now_utime);
  // The source gave an unreadable frame (`reason` lower_case) or lost the
  // device, or reopened it.
  void OnBadFrame(const std::string& reason, const std::string& error, int64_t now_utime);
  void OnSourceUp(const std::string& description, const std::vector<std::string>& refused,
                  int64_t now_utime);
  void OnSourceDown(const std::string& error, int64_t now_utime);
  // A set-up problem found before the first frame that makes every pose
  // wrong by a known amount but leaves the camera running (a synthetic
  // camera's calibration of another lens, SimCalibrationMismatch): counted
  // under `counter` and kept as the last error, so STATUS shows it.
  void OnSetupProblem(const std::string& counter, const std::string& error, int64_t now_utime);
  void OnEndOfStream(int64_t now_utime);
  void Tick(int64_t now_utime);
  void Stop(int64_t now_utime);

  const StatusReporter& status() const { return status_; }
  int64_t frames_processed() const { return frames_processed_; }
  // The last frame's results, for tests and the benchmark.
  const std::vector<vision::RobotObservation>& last_observations() const { return observations_; }
  const MarkerPixels& last_marker_pixels() const { return last_pixels_; }
  bool calibrated() const { return calibration_.has_value(); }
  // The timing each marker's time is computed with (options.device_timing
  // when given, else the site camera's keys).
  const calib::CameraTiming& timing() const { return timing_; }

 private:
  // The steps of OnFrame. Counts the frame (and the frames missed before
  // it); false, counted, when its size is not the camera's.
  bool AcceptFrame(const camera::Frame& frame, int64_t now_utime);
  // Every blob of the frame once, from the full-frame search (when `full`)
  // and the planned windows; false, counted, when the image cannot be
  // decoded.
  bool DetectBlobs(const camera::Frame& frame, const std::vector<vision::SearchPlan>& plans,
                   bool full, std::vector<vision::Blob>* all, int64_t now_utime);
  // The frame's MARKER_PIXELS (without its processing time): each blob with
  // the robot and role the tracker gave it, cut to the wire cap with the
  // robots' markers first.
  MarkerPixels MarkerPixelsOf(const camera::Frame& frame, bool full,
                              const std::vector<vision::Blob>& all);
  bool SearchFullFrame(camera::FrameImage* image, std::vector<vision::Blob>* blobs,
                       std::string* error);
  // Tracking from one frame's blobs (each marker once): sets observations_
  // and the per-robot state lines and counters.
  void Track(int64_t capture_utime, const std::vector<vision::SearchPlan>& plans,
             const std::vector<vision::Blob>& blobs, int64_t now_utime);
  void PublishPoses(int64_t capture_utime, int64_t frame_seq, int64_t latency_us);
  void OnHint(const pose2d_t& msg, const MessageInfo& info);
  // The low-rate images after a frame's work: the preview and the detector
  // view, each when due.
  void PublishLowRateViews(const camera::Frame& frame, int64_t now_utime);
  void MaybePublishPreview(const camera::Frame& frame);
  void MaybePublishDetectorView(const camera::Frame& frame, int64_t now_utime);
  // A CAMERA_DETECTOR_VIEW_REQUEST: checked, then turns the view on (or off).
  void OnDetectorViewRequest(const detector_view_request_t& msg, const MessageInfo& info);
  bool CheckDetectorViewRequest(const DetectorViewRequest& request, std::string* reason,
                                std::string* error) const;
  bool MapMarker(const vision::Blob& blob, double radius_m, double height_m, double* x_m,
                 double* y_m) const;
  // Frame timestamps: the spread of the intervals between consecutive
  // frames estimates the USB jitter no camera reports.
  void ObserveCaptureTime(int64_t capture_utime, int64_t frame_seq);
  double TimingSigmaS() const;
  // A robot's floor velocity from its recent poses (zero when unknown).
  Eigen::Vector2d Velocity(size_t robot) const;

  const Camera& camera_;
  // A copy: what ReceivePose checks a hint's robot against.
  Site site_;
  std::optional<calib::Calibration> calibration_;
  Bus* bus_;
  CameraNodeOptions options_;
  StatusReporter status_;
  CameraSetup setup_;
  std::string setup_error_;
  std::unique_ptr<vision::MarkerDetector> detector_;
  std::unique_ptr<vision::RobotTracker> tracker_;
  std::vector<vision::RobotObservation> observations_;
  std::vector<int> last_states_;
  MarkerPixels last_pixels_;
  int64_t last_seq_ = -1;
  int64_t bad_since_last_ = 0;
  int64_t last_preview_utime_ = 0;
  // The detector view: asked until this time (now_utime's clock), at this
  // rate, of this full-resolution region (empty: the whole frame).
  int64_t detector_view_until_utime_ = 0;
  double detector_view_request_hz_ = 0.0;
  cv::Rect detector_view_region_;
  int64_t last_detector_view_utime_ = 0;
  // The last hint per robot, as a pixel (the view's "expected here").
  struct HintPixel {
    double u_px, v_px;
    int64_t utime;
  };
  std::map<int, HintPixel> hint_px_;
  int64_t frames_processed_ = 0;
  calib::CameraTiming timing_;
  // Running mean and variance of the interval between consecutive frames, us.
  int64_t last_capture_utime_ = 0;
  int64_t last_capture_seq_ = -1;
  int64_t intervals_ = 0;
  double interval_mean_us_ = 0.0;
  double interval_var_us2_ = 0.0;
  struct PoseSample {
    int64_t utime;
    double x_m, y_m;
  };
  std::vector<std::deque<PoseSample>> recent_poses_;
  // Last: ended first, before anything the handlers use.
  Subscriptions subscriptions_{bus_};
};

}  // namespace roomfix

#endif  // ROOMFIX_CAMERA_PROC_CAMERA_NODE_H_
