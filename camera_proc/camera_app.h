#ifndef ROOMFIX_CAMERA_PROC_CAMERA_APP_H_
#define ROOMFIX_CAMERA_PROC_CAMERA_APP_H_

// camera_proc around its node: the read loop that keeps a live camera open.
// The main chooses the camera and makes its frame source
// (camera_io/camera_source.h; the synthetic camera's in
// sim/sim_camera_source.h) and hands the source to RunCameraSource.

#include <cstdint>
#include <string>

#include "camera_io/frame_source.h"
#include "camera_proc/camera_node.h"
#include "msgio/bus.h"

namespace roomfix {

// How RunCameraSource paces itself.
struct CameraLoopOptions {
  // Stop after this long (<= 0: until a shutdown is asked for or a file
  // source ends).
  double duration_s = 0.0;
  // The wait before reopening a lost live camera starts at first_reopen_s and
  // doubles up to reopen_max_s.
  double first_reopen_s = 0.1;
  double reopen_max_s = 2.0;
  // Hints (other sensors' poses) are dispatched for at most this long before
  // each frame: a third of a 30 fps frame period, so a flood cannot starve
  // the camera.
  int64_t hint_drain_budget_us = 10000;

  bool IsValid(std::string* error) const;
};

// The read loop: opens the source (a live one is retried with a doubling
// wait, a webcam unplugged and plugged back in comes back on its own),
// dispatches the bus, reads frames into the node (an unreadable one counted
// under its camera::FrameProblem), reopens a lost device, and ends at the end
// of a file source, at the duration or when a shutdown is asked for.
// Stops the node and closes the source (joining a synthetic camera's
// renderer). Returns 0, or 1 when a file source cannot be opened (the reason
// in *error) or LCM fails (the reason logged).
int RunCameraSource(camera::FrameSource* source, CameraNode* node, Bus* bus,
                    const CameraLoopOptions& options, std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_CAMERA_PROC_CAMERA_APP_H_
