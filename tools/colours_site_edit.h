#ifndef ROOMFIX_TOOLS_COLOURS_SITE_EDIT_H_
#define ROOMFIX_TOOLS_COLOURS_SITE_EDIT_H_

#include <string>
#include <vector>

#include "core/vision/colour_learning.h"
#include "core/world/site.h"

namespace roomfix {

// The site file's text with the HSV boxes of the named classes of camera
// `camera_id` replaced, everything else (comments, order, other cameras)
// kept byte for byte. Each class must be in the camera's marker_classes
// with hsv_min and hsv_max written as flow lists ([h, s, v]). False with
// the reason otherwise.
bool ReplaceClassBoxes(const std::string& site_text, int camera_id,
                       const std::vector<vision::LearnedClass>& classes, std::string* out,
                       std::string* error);

// roomfix colours' output: without `out_path` the classes as site-file
// lines on stdout; with it a copy of the site file with the learned boxes,
// checked as a site (no overlapping classes) before it is written. The
// site's classes not learned keep their boxes (said). Exit code.
int WriteClasses(const std::string& site_path, const std::string& out_path, const Camera& camera,
                 const std::vector<vision::LearnedClass>& classes);

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_COLOURS_SITE_EDIT_H_
