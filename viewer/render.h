#ifndef ROOMFIX_VIEWER_RENDER_H_
#define ROOMFIX_VIEWER_RENDER_H_

#include <opencv2/core.hpp>

#include "core/world/site.h"
#include "viewer/view_state.h"

namespace roomfix::viewer {

// The viewer's picture as a pure function of a ViewState: no display, no
// clock, no bus. The floor (room frame, x right, y up) fills the left of the
// picture; the side panel (processes, sources, legend, time, camera preview)
// the right options.panel_px.

// Room frame (metres) <-> picture pixels (u right, v down) for the floor area.
struct FloorMapping {
  double scale_px_per_m = 1.0;
  // Pixel of the room origin (0, 0).
  double u0_px = 0.0;
  double v0_px = 0.0;

  // x right, y up on screen: v decreases as y grows.
  cv::Point2d ToPixel(double x_m, double y_m) const;
  void ToFloor(cv::Point2d px, double* x_m, double* y_m) const;
};

// Zoom 1 fits the room rectangle plus a 0.3 m margin into the floor area
// ((width_px - panel_px) x height_px), keeping aspect, centred; pan moves the
// centre (metres), zoom scales about it. Never fails: options that fail
// IsValid are taken as Render takes them (below); a room that makes no sense
// (NaN, negative or beyond 1e6 m) is shown as if it were 1 x 1 m from the
// origin; a zero-size room fits its margin.
FloorMapping MakeFloorMapping(const Site& site, const RenderOptions& options);

// Colours, BGR. Sources: camera orange, ultrasound blue, fused green, ground
// truth near-black; chosen apart in hue and lightness so that each stays
// recognisable on the light floor and when faded along a trail.
cv::Scalar SourceColour(PoseSource source);
// Rejected ranges, lost tracks and failed processes (red).
cv::Scalar WarningColour();
// Receivers (dark purple squares): apart from every source colour, so that a
// range circle's centre is not mistaken for a track.
cv::Scalar ReceiverColour();
// Fill of a fixed obstacle's footprint (site `obstacles`, blue-grey).
cv::Scalar ObstacleColour();
// Fill of a stale track's disc (grey), under a dark 'X'.
cv::Scalar StaleColour();
// The room's floor (off-white); outside the room is a shade darker.
cv::Scalar FloorColour();

// Draws the state into *image, a CV_8UC3 picture of options.width_px x
// options.height_px, reallocated only when its size or type differs (a
// 30 fps loop does not allocate). Options that fail IsValid are drawn with
// the nearest valid ones (sizes clamped, a bad zoom 1, a bad pan 0), and any
// state is drawn without crashing: NaN or huge poses, covariances, ranges
// and times are skipped or clipped, an undecodable preview is left out.
//
// The static background (floor, grid, room outline, axes, receivers, camera
// footprints) is cached per thread, keyed on the site's geometry and the
// options, and copied each frame; the result is the same as drawing it anew.
void Render(const ViewState& state, const RenderOptions& options, cv::Mat* image);

}  // namespace roomfix::viewer

#endif  // ROOMFIX_VIEWER_RENDER_H_
