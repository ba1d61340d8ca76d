#ifndef ROOMFIX_MSGIO_POSE_TRACKS_H_
#define ROOMFIX_MSGIO_POSE_TRACKS_H_

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/analysis/track_error.h"

namespace roomfix {

// One pose as the analysis needs it.
struct PoseSample {
  // When the pose is valid (the measurement time).
  int64_t utime = 0;
  double x_m = 0.0;
  double y_m = 0.0;
  // NaN when unknown.
  double heading_rad = 0.0;
  // Measurement to publish, as the publisher stamped it, microseconds.
  int64_t latency_us = 0;
  // When the logger received it: the log event's time.
  int64_t recv_utime = 0;
  bool degraded = false;
  // The pose's (x, y) covariance, m^2, as published (NaN when it has none).
  double cov_xx_m2 = 0.0;
  double cov_xy_m2 = 0.0;
  double cov_yy_m2 = 0.0;
};

// Every pose of one source ("camera", "ultrasound", "fused",
// "ground_truth") for one robot, sorted by utime. Lost poses (no position)
// are only counted.
struct PoseTrack {
  std::string source;
  int robot_id = 0;
  std::vector<PoseSample> samples;
  int lost = 0;

  std::vector<analysis::TimedPosition> Positions() const;
};

// What reading a log found besides poses.
struct LogReadReport {
  std::string path;
  int64_t events = 0;
  int64_t pose_events = 0;
  // POSE_* events refused before decoding as pose2d_t (DecodeChecked), in
  // total and by reason (wire_refusal::*).
  int64_t undecodable = 0;
  std::map<std::string, int64_t> refused;
  // Bytes were skipped (corrupt regions, a truncated end); the good events
  // around them were read. `damage` is LogReader::DamageSummary().
  bool damaged = false;
  int64_t bytes_skipped = 0;
  std::string damage;
  // Offset just past the last good event.
  int64_t bytes_read = 0;
  int64_t file_size = 0;
  // Set when the file could not be opened at all.
  std::string error;
};

struct PoseLogs {
  // (source, robot id) -> track; several logs are merged.
  std::map<std::pair<std::string, int>, PoseTrack> tracks;
  std::vector<LogReadReport> logs;
};

// Reads every pose2d_t on POSE_* channels of the logs (written by
// roomfix_logger or lcm-logger). A pose that appears twice (same time and
// position: overlapping logs) counts once. A log that cannot be opened or that is
// damaged is reported in `logs` and its readable part used; nothing throws.
// `progress`, when given, is called with the fraction of all bytes read so
// far (0 to 1), at most every 64 KiB.
PoseLogs ReadPoseLogs(const std::vector<std::string>& paths,
                      const std::function<void(double fraction)>& progress = {});

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_POSE_TRACKS_H_
