#ifndef ROOMFIX_CAMERA_IO_FRAME_PROBLEM_H_
#define ROOMFIX_CAMERA_IO_FRAME_PROBLEM_H_

namespace roomfix::camera {

// Why a frame (or image file) that arrived could not be handed over, decided
// where the failure is seen (libjpeg's message code, the header reader, the
// size check), so no caller has to search the text of a reason. The text
// beside it says the detail for a person; this says the kind for a counter.
enum class FrameProblem {
  kNone,
  kEmpty,       // no bytes, or an empty decoded buffer
  kTruncated,   // the data stops early: a header cut short, no JPEG end marker,
                // libjpeg's premature end of file or of a data segment
  kWrongSize,   // the header states a size over the camera's (not decoded)
  kUnreadable,  // anything else: not an image format read here, corrupt data
};

// The camera_proc STATUS counter a frame with this problem is counted under
// ("empty_frame", "truncated_frame", "wrong_frame_size", "unreadable_frame";
// "" for kNone).
inline const char* FrameProblemCounter(FrameProblem problem) {
  switch (problem) {
    case FrameProblem::kNone:
      return "";
    case FrameProblem::kEmpty:
      return "empty_frame";
    case FrameProblem::kTruncated:
      return "truncated_frame";
    case FrameProblem::kWrongSize:
      return "wrong_frame_size";
    case FrameProblem::kUnreadable:
      break;
  }
  return "unreadable_frame";
}

}  // namespace roomfix::camera

#endif  // ROOMFIX_CAMERA_IO_FRAME_PROBLEM_H_
