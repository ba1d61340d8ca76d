#ifndef ROOMFIX_CORE_WORLD_POSE_SOURCE_H_
#define ROOMFIX_CORE_WORLD_POSE_SOURCE_H_

#include <cstddef>
#include <cstdint>

namespace roomfix {

// Which sensor (or which estimate) a pose came from: the one enum for it in
// every layer (the fusion filter's measurements, msgio's Pose2d, the
// viewer's tracks). It lives in core/world, the bottom of core, because core
// never sees msgio; it is numbered as the wire is (pose2d_t::SOURCE_*, which
// msgio/message_conversions.cc static_asserts), so a message's source casts
// to it and back unchanged.
enum class PoseSource : int8_t {
  kUnknown = 0,
  kCamera = 1,
  kUltrasound = 2,
  kFused = 3,
  kGroundTruth = 4,
};

// One past the largest source: the size of an array indexed by a source's
// number (kUnknown's entry unused).
inline constexpr size_t kNumPoseSources = 5;

// "camera", "ultrasound", "fused", "ground_truth" or "unknown" (also for a
// value outside the enum): counter names (fusion_proc's inputs_camera), logs
// and the analysis's grouping.
inline const char* PoseSourceName(PoseSource source) {
  switch (source) {
    case PoseSource::kCamera:
      return "camera";
    case PoseSource::kUltrasound:
      return "ultrasound";
    case PoseSource::kFused:
      return "fused";
    case PoseSource::kGroundTruth:
      return "ground_truth";
    case PoseSource::kUnknown:
      break;
  }
  return "unknown";
}

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_POSE_SOURCE_H_
