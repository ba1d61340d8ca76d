#ifndef ROOMFIX_VIEWER_FOOTPRINT_H_
#define ROOMFIX_VIEWER_FOOTPRINT_H_

#include <vector>

#include "core/world/site.h"
#include "viewer/view_state.h"

namespace roomfix::viewer {

// Each camera's footprint: the floor polygon its image covers at
// `height_m` (the markers' plane, so a robot inside it is seen), from the
// calibration file the site names when it loads (a full model; a 9-region
// table is valid at its own height only and cannot say), else from the
// nominal model (straight down from mount_position_m, field_of_view_deg
// across the width: what a camera not yet calibrated should roughly see).
// The image border is walked (kFootprintSamplesPerSide pixels per side) and
// each pixel mapped to the plane; pixels whose ray misses it (beyond the
// horizon of a wide lens) are left out, so the polygon is the part of the
// border that does reach the floor.
inline constexpr int kFootprintSamplesPerSide = 32;
std::vector<CameraFootprint> CameraFootprints(const Site& site, double height_m);

// The marker height of the site's cameras' robots (the first listed), else
// 0: the plane the viewer draws footprints in.
double FootprintHeight(const Site& site);

}  // namespace roomfix::viewer

#endif  // ROOMFIX_VIEWER_FOOTPRINT_H_
