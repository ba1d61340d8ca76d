#ifndef ROOMFIX_CORE_CALIB_REGION_MODEL_H_
#define ROOMFIX_CORE_CALIB_REGION_MODEL_H_

#include <array>
#include <string>
#include <vector>

#include "core/calib/camera_fit.h"

namespace roomfix::calib {

// The reference's piecewise-linear camera model. The image is split into 3 x
// 3 regions at two u and two v boundaries (default: thirds); in each region
// each floor axis is a straight line of one pixel axis:
//
//   x_m = (u_px - os1_x) / C_x + os2_x
//   y_m = (v_px - os1_y) / C_y + os2_y
//
// os1 in pixels, C in pixels per metre, os2 in metres. Only the slope 1 / C
// and the intercept are determined by data; os1 is a free anchor, which the
// fit puts at the region's pixel centre so that os2 is the floor coordinate
// seen there. v grows down the image while room y may grow up (a ceiling
// camera looking down, NominalCamera): C_y is then negative.
//
// The reference worked in centimetres: its table's C_calib is in pixels per
// cm and os2 in cm. Converting: C [px/m] = 100 C [px/cm], os2 [m] =
// os2 [cm] / 100, os1 unchanged (calibration_file.h reads the table either
// way, `length_unit: cm` or `m`).
//
// Limits (why roomfix has the full model, fisheye_camera.h): x depends on u
// only and y on v only, so the lens's radial distortion, which bends grid
// lines into curves, is approximated by 9 chords; the map jumps at region
// boundaries; and it is valid only for markers at the height it was
// calibrated at (a marker 0.2 m lower appears nearer the image centre by
// about 0.2 / (camera height) of its distance from the nadir; the tests
// measure what that costs).
struct RegionAxis {
  double os1_px = 0.0;
  double c_px_per_m = 1.0;
  double os2_m = 0.0;
};

struct Region {
  RegionAxis x;  // from u
  RegionAxis y;  // from v
};

struct RegionModel {
  int width_px = 0;
  int height_px = 0;
  // Column boundaries: column 0 is u < u_boundaries_px[0], column 2 is
  // u >= u_boundaries_px[1]; likewise rows from v, row 0 at the top.
  std::array<double, 2> u_boundaries_px = {0.0, 0.0};
  std::array<double, 2> v_boundaries_px = {0.0, 0.0};
  // Row-major, top row first: regions[3 * row + col].
  std::array<Region, 9> regions{};
  // The marker height the table was calibrated at (metres above the floor).
  double calibration_height_m = 0.0;

  // The region (0..8) a pixel falls in; pixels outside the image go to the
  // nearest edge region.
  int RegionIndex(double u_px, double v_px) const;

  // Pixel to floor, for a marker at calibration_height_m (the model knows no
  // other height: a caller holding a different height uses MapAtHeight,
  // which refuses).
  void Map(double u_px, double v_px, double* x_m, double* y_m) const;

  // As Map, refusing (false, *error says why) a height more than
  // kHeightToleranceM from calibration_height_m, a pixel more than
  // CameraModel::kPixelMarginPx outside the image, or a non-finite input. A
  // refusal rather than a warning: the error grows with the height
  // difference and with the distance from the nadir (centimetres for 0.2 m,
  // region_model_test), and a silently wrong position is worse than none.
  bool MapAtHeight(double u_px, double v_px, double height_m, double* x_m, double* y_m,
                   std::string* error) const;

  // Floor to pixel. The forward map is discontinuous at region boundaries,
  // so a floor point may have no preimage (it falls in a gap between two
  // regions' lines) or two. Each region's inverse u = os1 + C (x - os2) is
  // tried in turn; the first region whose answer lies inside it wins,
  // otherwise the region whose answer lies nearest outside it (the answer
  // then jumps across a gap of a few pixels). Refuses (false) the same
  // heights, non-finite inputs and answers outside the image as
  // MapAtHeight.
  bool InverseAtHeight(double x_m, double y_m, double height_m, double* u_px, double* v_px,
                       std::string* error) const;

  // Checks the sizes, ordered boundaries inside the image, finite values and
  // non-zero C. One line on failure.
  bool IsValid(std::string* error) const;

  static constexpr double kHeightToleranceM = 0.001;
};

// An empty model over a width x height image with the boundaries at thirds.
RegionModel ThirdsRegionModel(int width_px, int height_px);

// "row 0, col 2 (u 1280..1920 px, v 0..360 px)" for messages.
std::string DescribeRegion(const RegionModel& model, int index);

struct RegionFitSummary {
  // False: `message` says why (one line naming the region when a region
  // lacks points).
  bool usable = false;
  std::string message;
  RegionModel model;
  // Per input point: floor distance between Map(u, v) and (x, y), metres;
  // and pixel distance between InverseAtHeight(x, y) and (u, v).
  std::vector<double> residual_m;
  std::vector<double> residual_px;
  double rms_m = 0.0;
  double max_m = 0.0;
  int worst_index = -1;
};

// Fits the table: for each region and axis, ordinary least squares of the
// floor coordinate on the pixel coordinate over the points whose pixel lies
// in the region (x on u, y on v), then os1 = the region's pixel centre and
// os2 = the line's value there. `layout` gives the image size and the
// boundaries; its regions are ignored.
//
// Rejected (usable false, one line): an invalid layout; non-finite values;
// a pixel outside the image (more than CameraModel::kPixelMarginPx);
// heights that differ by more than kHeightToleranceM (one table is one
// height); a region-axis with fewer than 2 points of distinct pixel
// coordinate (spread below 1 px: the slope is undetermined), naming the
// region; a slope of zero.
RegionFitSummary FitRegions(const std::vector<Correspondence>& points, const RegionModel& layout);

}  // namespace roomfix::calib

#endif  // ROOMFIX_CORE_CALIB_REGION_MODEL_H_
