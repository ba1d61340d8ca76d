#include "msgio/pose_tracks.h"

#include <sys/stat.h>

#include <algorithm>
#include <cmath>

#include "msgio/channels.h"
#include "msgio/log.h"
#include "msgio/message_conversions.h"
#include "msgio/wire_check.h"

namespace roomfix {

std::vector<analysis::TimedPosition> PoseTrack::Positions() const {
  std::vector<analysis::TimedPosition> out;
  out.reserve(samples.size());
  for (const PoseSample& s : samples) out.push_back({s.utime, s.x_m, s.y_m});
  return out;
}

PoseLogs ReadPoseLogs(const std::vector<std::string>& paths,
                      const std::function<void(double)>& progress) {
  PoseLogs out;
  int64_t total_bytes = 0;
  for (const std::string& path : paths) {
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) total_bytes += st.st_size;
  }
  int64_t done_bytes = 0;
  for (const std::string& path : paths) {
    LogReadReport report;
    report.path = path;
    std::string error;
    auto reader = LogReader::Open(path, &error);
    if (reader == nullptr) {
      report.error = error;
      out.logs.push_back(report);
      continue;
    }
    LogEvent e;
    int64_t last_progress = 0;
    while (reader->Next(&e)) {
      ++report.events;
      if (progress && total_bytes > 0 && reader->bytes_read() - last_progress >= (64 << 10)) {
        last_progress = reader->bytes_read();
        progress(static_cast<double>(done_bytes + last_progress) / total_bytes);
      }
      if (e.channel.rfind(kPoseChannelPrefix, 0) != 0) continue;
      ++report.pose_events;
      pose2d_t msg{};
      std::string reason;
      if (!DecodeChecked(e.data.data(), static_cast<int>(e.data.size()), &msg, &reason)) {
        ++report.undecodable;
        ++report.refused[reason];
        continue;
      }
      const Pose2d p = FromMessage(msg);
      PoseTrack& track = out.tracks[{PoseSourceName(p.source), p.robot_id}];
      track.source = PoseSourceName(p.source);
      track.robot_id = p.robot_id;
      if (p.status == PoseStatus::kLost || !std::isfinite(p.x_m) || !std::isfinite(p.y_m)) {
        ++track.lost;
        continue;
      }
      PoseSample s;
      s.utime = p.utime;
      s.x_m = p.x_m;
      s.y_m = p.y_m;
      s.heading_rad = p.heading_rad;
      s.latency_us = p.latency_us;
      s.recv_utime = e.utime;
      s.degraded = p.status == PoseStatus::kDegraded;
      s.cov_xx_m2 = p.covariance[0][0];
      s.cov_xy_m2 = 0.5 * (p.covariance[0][1] + p.covariance[1][0]);
      s.cov_yy_m2 = p.covariance[1][1];
      track.samples.push_back(s);
    }
    report.damaged = reader->damaged();
    report.bytes_skipped = reader->bytes_skipped();
    report.damage = reader->DamageSummary();
    report.bytes_read = reader->bytes_read();
    report.file_size = reader->file_size();
    done_bytes += report.file_size;
    out.logs.push_back(report);
  }
  for (auto& [key, track] : out.tracks) {
    std::stable_sort(track.samples.begin(), track.samples.end(),
                     [](const PoseSample& a, const PoseSample& b) { return a.utime < b.utime; });
    // The same pose recorded twice (overlapping logs, two loggers on one
    // bus) is one measurement: keep the first copy.
    track.samples.erase(std::unique(track.samples.begin(), track.samples.end(),
                                    [](const PoseSample& a, const PoseSample& b) {
                                      return a.utime == b.utime && a.x_m == b.x_m && a.y_m == b.y_m;
                                    }),
                        track.samples.end());
  }
  if (progress) progress(1.0);
  return out;
}

}  // namespace roomfix
