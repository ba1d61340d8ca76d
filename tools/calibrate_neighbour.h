#ifndef ROOMFIX_TOOLS_CALIBRATE_NEIGHBOUR_H_
#define ROOMFIX_TOOLS_CALIBRATE_NEIGHBOUR_H_

#include <string>
#include <vector>

#include "core/calib/calibration_file.h"
#include "core/calib/camera_fit.h"
#include "core/world/site.h"

namespace roomfix {

// `roomfix calibrate --shared-images CSV --neighbour CAL.yaml`: a camera
// fitted against an already calibrated neighbour from points both see
// (docs/calibration.md, "A camera beside a calibrated one").
//
// The CSV has the header `image,neighbour_image,height_m` and one line per
// placement of a marker in the two cameras' overlap: this camera's image and
// the neighbour's of the same marker at the same moment (paths relative to
// the CSV), and the marker's height. Nothing is surveyed: the marker's floor
// position is where the neighbour's calibration maps its pixel at that
// height, so the fit pulls this camera onto the neighbour's frame where
// they overlap (the two then agree there to the neighbour's own accuracy
// plus the detector's). In each image the marker is found by camera_proc's
// detector with `camera`'s colour class `class_name`; an image must show
// exactly one blob of it.
//
// Appends one correspondence per line (this camera's pixel, the mapped
// floor position) and its CSV line number; prints each to stdout. False with
// one line (file:line: what) for a malformed CSV, an unreadable image, not
// exactly one marker, or a neighbour pixel its calibration cannot map.
bool AddSharedImagePoints(const std::string& csv_path, const calib::Calibration& neighbour,
                          const Camera& camera, const std::string& class_name,
                          std::vector<calib::Correspondence>* points, std::vector<int>* lines,
                          std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_CALIBRATE_NEIGHBOUR_H_
