#ifndef ROOMFIX_MSGIO_CHANNELS_H_
#define ROOMFIX_MSGIO_CHANNELS_H_

// Every LCM channel roomfix publishes or reads, named once: docs/messages.md
// has the table of who publishes what on each, with its type. A channel name
// is a wire contract (logs, lcm-spy, the Java and Python readers spell it
// too), so code names it by these constants, never by a bare string.

namespace roomfix {

// marker_pixels_t: the markers camera_proc found in each frame.
inline constexpr char kMarkerPixelsChannel[] = "MARKER_PIXELS";
// range_set_t: every range of one beacon firing (zigbee_bridge, roomfix_sim).
inline constexpr char kRangesChannel[] = "RANGES";

// pose2d_t, one channel per source; every pose channel starts with
// kPoseChannelPrefix (the viewer subscribes to kPoseChannelPattern, the
// analysis reads every channel with the prefix).
inline constexpr char kCameraPoseChannel[] = "POSE_CAMERA";
inline constexpr char kUltrasoundPoseChannel[] = "POSE_ULTRASOUND";
inline constexpr char kFusedPoseChannel[] = "POSE_FUSED";
inline constexpr char kGroundTruthPoseChannel[] = "POSE_GROUND_TRUTH";
inline constexpr char kPoseChannelPrefix[] = "POSE_";
inline constexpr char kPoseChannelPattern[] = "POSE_.*";

// process_status_t: every process's heartbeat. `roomfix replay` writes the
// heartbeats of the nodes it re-ran (host "replay", pid 0: the live STATUS
// names the replaying machine's pid, which would make two replays differ) to
// a channel of their own, so no tool takes them for a live process
// (docs/replay.md).
inline constexpr char kStatusChannel[] = "STATUS";
inline constexpr char kReplayStatusChannel[] = "REPLAY_STATUS";
// site_t: the site file a process runs with.
inline constexpr char kSiteChannel[] = "SITE";

// camera_proc's pictures for people (never used to measure): image_t, and
// detector_view_t on request (detector_view_request_t).
inline constexpr char kCameraPreviewChannel[] = "CAMERA_PREVIEW";
inline constexpr char kDetectorViewChannel[] = "CAMERA_DETECTOR_VIEW";
inline constexpr char kDetectorViewRequestChannel[] = "CAMERA_DETECTOR_VIEW_REQUEST";

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_CHANNELS_H_
