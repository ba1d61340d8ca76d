#ifndef ROOMFIX_SIM_GROUND_TRUTH_NODE_H_
#define ROOMFIX_SIM_GROUND_TRUTH_NODE_H_

#include <cstdint>
#include <string>

#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/channels.h"
#include "msgio/process.h"

namespace roomfix {

struct GroundTruthNodeOptions {
  // Samples per second of every simulated robot's true pose.
  double rate_hz = 30.0;
  // Host time that is t = 0 of the trajectories.
  int64_t start_utime = 0;

  bool IsValid(std::string* error) const;
};

// Publishes the simulated robots' true poses (pose2d_t, source ground_truth)
// on POSE_GROUND_TRUTH at a fixed rate, and the STATUS heartbeat.
//
// Samples fall on a fixed grid, start_utime + k / rate_hz, and each carries
// its grid time as utime (the time the pose is true at), so the poses do not
// depend on when Tick happens to run. When Tick comes late and several
// samples are due, only the newest is published and the skipped ones are
// counted as "late_samples": ground truth is for comparison, not a queue.
class GroundTruthNode {
 public:
  GroundTruthNode(const Site& site, Bus* bus, const GroundTruthNodeOptions& options);

  void Tick(int64_t now_utime);
  // Says goodbye: a last heartbeat in state STOPPING.
  void Stop(int64_t now_utime);

  const StatusReporter& status() const { return status_; }
  int64_t samples_published() const { return next_sample_; }

 private:
  const Site& site_;
  Bus* bus_;
  GroundTruthNodeOptions options_;
  StatusReporter status_;
  int64_t next_sample_ = 0;
};

}  // namespace roomfix

#endif  // ROOMFIX_SIM_GROUND_TRUTH_NODE_H_
