#ifndef ROOMFIX_CORE_VISION_ROBOT_TRACKER_H_
#define ROOMFIX_CORE_VISION_ROBOT_TRACKER_H_

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/vision/marker_detector.h"

namespace roomfix::vision {

// A robot as the camera sees it: the classes (indices into the detector's
// classes) of its position and heading markers.
struct TrackedRobotSpec {
  int robot_id = 0;
  int position_class = -1;
  int heading_class = -1;
  // Expected radius of the position marker in full-resolution pixels (from
  // the calibration or the nominal lens); used to size windows and to judge
  // how far the heading marker may be from the position marker.
  double position_radius_px = 15.0;
};

struct TrackerOptions {
  // Fastest the marker can move across the image, pixels per second (the
  // node derives it from the robot's top speed and the lens).
  double max_speed_px_per_s = 600.0;
  // Window half-size = margin + radius * radius_factor + speed * dt.
  double window_margin_px = 24.0;
  double window_radius_factor = 4.0;
  // The heading marker is looked for within this many position-marker
  // radii of the position marker's centre.
  double heading_search_radii = 5.0;
  // After this long without a confirmed find, a robot is kLost and searched
  // in the full frame.
  double lost_after_s = 0.5;
  // A position hint (SetHint) counts for this long around its time.
  double hint_max_age_s = 1.0;
  // Identification by marker code (the site's marker_code): any class may
  // be a position or a heading marker, a robot is the one whose ordered
  // class pair (position, heading) a pair of blobs shows, and a blob's role
  // comes from its size next to its partner (UpdateByCode). False: a robot
  // is its classes, as in the one-robot demo.
  bool identify_by_code = false;
  // Centre-to-centre distance of the two markers in position-marker radii,
  // and the heading marker's diameter over the position marker's.
  double heading_offset_radii = 2.0;
  double heading_size_ratio = 0.5;
  // A pair's measured distance may differ from heading_offset_radii times
  // the position blob's radius by this fraction: a fisheye squeezes a disc
  // radially towards the image's edge (down to 0.6 of the tangential scale
  // at the 6 x 4 m room's corners), which moves the ratio by up to +-35 %.
  double heading_offset_tolerance = 0.45;
  // A blob is *clipped* when its disc, its equivalent radius times
  // clip_radius_factor plus clip_margin_px around its centroid, reaches past
  // the edge of the image, or of the window it was searched in when the
  // frame had no full-frame search. A marker cut by an edge is measured
  // small, with its centroid moved inwards (by 0.42 of its radius for a half
  // disc), yet the cut still lies within that reach: a disc's segment has
  // its centroid nearer the chord than its equivalent radius (a half disc:
  // 0.42 R against 0.71 R; a disc missing a cap of height h: R - h against
  // R - O(h^1.5)). The factor covers a fisheye's elongation: an ellipse of
  // radial squeeze 0.66 (a 120-degree lens's corners) reaches at most 1.10
  // equivalent radii towards a 4:3 image's top edge; the margin covers the
  // mask's blur. A clipped blob never identifies a robot nor gives it a pose
  // (its size decides its role, its centroid is biased): see UpdateByCode.
  double clip_radius_factor = 1.1;
  double clip_margin_px = 2.0;
  // Robots out of view (never found, or lost: kSearching, kLost) are looked
  // for by a full-frame search once in this many frames (Update calls), not
  // in every one: a camera in a hall always has robots out of its view, and
  // a full search costs 5 to 10 times a frame of windows. A robot that
  // enters the view whole is acquired within this many frames (at 30 fps,
  // 4 frames: 0.13 s, 4 cm at 0.3 m/s, while an overlap between cameras is
  // metres wide). A tracked robot whose window missed (within lost_after_s)
  // and a kAmbiguous robot still get a full-frame search in the next frame,
  // and a frame searched in full for any robot serves every robot. With a
  // marker code a robot out of view is identified only from a full-frame
  // search (its code must be seen once in the whole frame); its code seen
  // in another robot's window asks for one in the next frame. 1: every
  // frame, as before this option.
  int absent_search_period_frames = 4;
  // Most blobs one frame may hand in (all lists together). A frame with more
  // (a hostile or cluttered view: thousands of coloured specks) identifies
  // no robot: every robot is not found, "too_many_blobs". Bounds the work:
  // merging the lists is quadratic in the count (at most 512^2 / 2
  // comparisons), pairing near-linear (a sweep along u). A hall camera
  // sees 2 blobs per robot in view; a marker's area filter keeps specks of
  // a few pixels out.
  int max_blobs = 512;
  // False only to measure what the clip rule prevents (tests, benchmarks):
  // every blob is then taken as whole, as before the rule.
  bool refuse_clipped = true;

  // False with a reason: a speed, size or time that is not positive and
  // finite, a tolerance outside [0, 1), a search period outside [1, 300].
  bool IsValid(std::string* error) const;
};

enum class TrackState {
  kSearching,  // never found, or lost: full-frame search
  kTracking,   // found in the last frame(s): region search
  kAmbiguous,  // a full-frame search found more than one candidate that fits
  kLost,       // not confirmed for lost_after_s
};
const char* TrackStateName(TrackState state);

// What the tracker wants searched for one robot in the next frame.
struct SearchPlan {
  int robot_id = 0;
  bool full_frame = true;
  // Full-resolution rectangle (clipped to the image) when !full_frame.
  cv::Rect window;
};

struct RobotObservation {
  int robot_id = 0;
  TrackState state = TrackState::kSearching;
  bool found = false;        // position marker confirmed in this frame
  Blob position;             // valid when found
  bool has_heading = false;  // heading marker paired in this frame
  Blob heading;
  // Image-plane angle from the position to the heading marker, atan2(dv, du).
  double image_angle_rad = 0.0;
  // Candidates that fitted (kAmbiguous lists them all); for messages.
  int num_candidates = 0;
  std::string note;  // why not found / why ambiguous, one line
  // Why this frame's identification is in doubt, as a STATUS counter name
  // (empty when it is not): with a marker code "interleaved_markers",
  // "code_seen_twice" or "impossible_jump" (UpdateByCode states the rule);
  // in both modes "marker_clipped" (its markers were seen only cut by the
  // image's or a window's edge: no identity, no pose from them).
  std::string identity_problem;
};

// Region-of-interest tracking of several robots, each a pair of marker
// classes. Pure: time comes in as an argument. Per frame the caller asks
// Plan(), searches what it says (a window, or the full frame), and hands the
// blobs to Update(). Blobs outside a tracking robot's window are never
// assigned to it, so a similar object elsewhere cannot steal the track; at
// start-up (or when lost) a full-frame search that finds more than one
// position-marker candidate with a heading marker beside it leaves the robot
// kAmbiguous instead of picking one.
class RobotTracker {
 public:
  RobotTracker(std::vector<TrackedRobotSpec> robots, TrackerOptions options, int width_px,
               int height_px);

  std::vector<SearchPlan> Plan(int64_t utime) const;

  // `full_frame_blobs`: blobs from a full-frame search (empty when none ran);
  // `window_blobs[i]`: blobs found in plans[i].window for each non-full plan
  // (same order as Plan() returned). Returns one observation per robot, in
  // the order of the specs.
  //
  // `window_blobs` may hold one list per plan (empty for full-frame plans
  // and plans with no search) or one per window plan (a plan with a
  // non-empty window) only; both are accepted. A plan that is neither full
  // frame nor has a window searches nothing for its robot (out of view,
  // between full-frame searches: absent_search_period_frames). A tracking robot's
  // position marker must have its centroid inside its window (blobs outside
  // are ignored even when handed in); its heading marker may lie anywhere
  // within heading_search_radii * position_radius_px of it. A full-frame
  // search with several candidates still re-acquires a robot whose last
  // confirmed find was less than lost_after_s ago when exactly one
  // candidate lies within window_margin_px + max_speed_px_per_s * dt of its
  // last position. Robots with the same class pair never share a blob; a
  // robot found from the full frame restarts its velocity estimate. Robots
  // with the same class pair that were never found are kAmbiguous while the
  // full frame holds two or more candidates; a single candidate goes to the
  // first of them in spec order (such robots enter the view one at a time).
  std::vector<RobotObservation> Update(int64_t utime, const std::vector<SearchPlan>& plans,
                                       const std::vector<Blob>& full_frame_blobs,
                                       const std::vector<std::vector<Blob>>& window_blobs);

  // Where another sensor (the ultrasound, the fused track) puts a robot, as
  // a pixel and a radius of uncertainty: a full-frame search that finds
  // several candidates takes the one inside the radius when it is the only
  // one there, instead of staying kAmbiguous. A stale hint (older than
  // hint_max_age_s at the frame's time) is ignored.
  void SetHint(int robot_id, double u_px, double v_px, double radius_px, int64_t utime);

  const std::vector<TrackedRobotSpec>& robots() const { return robots_; }
  // The last Update's work in marker-code pairing: blob pairs compared.
  int64_t last_pairing_checks() const { return pairing_checks_; }

 private:
  // Update for identify_by_code. Every blob handed in (windows and full
  // frame, each once) is paired: a position blob p and a heading blob h form
  // a pair when h's radius over p's is nearer heading_size_ratio than 1 (in
  // log scale) and their distance is heading_offset_radii p-radii within
  // heading_offset_tolerance; the pair's classes are its code, and the code
  // names the robot. Lens scale cancels: both tests are ratios of blobs a
  // few centimetres apart. Then, per robot, with its gate the tracking
  // window's half-size around the prediction when it was found less than
  // lost_after_s ago (no gate otherwise):
  //  - a blob in two pairs with robots' codes (markers of neighbours
  //    interleaved): every robot of those pairs is not published this frame
  //    (kAmbiguous, identity_problem "interleaved_markers");
  //  - two pairs with its code inside the gate (or without a gate): not
  //    published (kAmbiguous, "code_seen_twice");
  //  - one inside and others outside: the inside one, published degraded
  //    (position only, "code_seen_twice"): its identity rests on the gate;
  //  - only pairs outside the gate (an identity swap, or a look-alike):
  //    not published ("impossible_jump") until the track is lost
  //    (lost_after_s), after which the code is taken wherever it is;
  //  - no pair: a lone blob of its position class, of the last position
  //    blob's size, inside the gate and in no pair is taken when it is the
  //    only one, degraded (no heading), as the demo does.
  // A pair with a clipped blob (TrackerOptions::clip_radius_factor) is
  // evidence, never an identification: it counts in the rules above as a
  // sighting of its code (and its blobs as used, for interleaving), but a
  // robot whose code is seen only in clipped pairs is not published from
  // them ("marker_clipped"; the lone-blob rule may still publish it
  // degraded from a whole position blob in its gate). A clipped blob is
  // never a lone position blob either.
  // Update's work, before the search bookkeeping.
  std::vector<RobotObservation> Identify(int64_t utime, const std::vector<SearchPlan>& plans,
                                         const std::vector<Blob>& full_frame_blobs,
                                         const std::vector<std::vector<Blob>>& window_blobs);
  // Per blob handed in (the full-frame list, then each window list): is it
  // clipped (TrackerOptions::clip_radius_factor)?
  struct ClipFlags {
    std::vector<bool> full;
    std::vector<std::vector<bool>> windows;
  };
  ClipFlags FindClipped(const std::vector<SearchPlan>& plans,
                        const std::vector<Blob>& full_frame_blobs,
                        const std::vector<std::vector<Blob>>& window_blobs) const;
  std::vector<RobotObservation> UpdateByCode(int64_t utime, const std::vector<SearchPlan>& plans,
                                             const std::vector<Blob>& full_frame_blobs,
                                             const std::vector<std::vector<Blob>>& window_blobs,
                                             const ClipFlags& clipped);
  // Update without a code (a robot is its two classes), on blobs of which
  // the clipped ones were left out.
  std::vector<RobotObservation> UpdateByClasses(int64_t utime, const std::vector<SearchPlan>& plans,
                                                const std::vector<Blob>& full_frame_blobs,
                                                const std::vector<std::vector<Blob>>& window_blobs);
  // Velocities, states and last positions from a frame's observations; a
  // find by a robot whose plan was a full-frame search (`full_plan`) is a
  // re-acquisition and restarts its velocity.
  void Bookkeep(int64_t utime, const std::vector<bool>& full_plan,
                const std::vector<bool>& ambiguous, std::vector<RobotObservation>* obs);

  // Stages both modes share. A robot found less than lost_after_s ago has a
  // gate (by code) or may be re-acquired near its last find (by classes).
  bool RecentlyFound(size_t i, int64_t utime) const;
  // Robot i's last find moved on by its velocity estimate to `utime`.
  void Predict(size_t i, int64_t utime, double* u_px, double* v_px) const;
  // Half-size of robot i's tracking window (and code gate) dt_s after its
  // last find: window_margin_px + radius * window_radius_factor + speed * dt.
  double WindowHalfPx(size_t i, double dt_s) const;
  std::string OutOfViewNote() const;

  // UpdateByClasses' stages (robot_tracker.cc says what each decides), on
  // the state they share within one frame.
  struct ClassesFrame;
  struct LookAlikes;
  void AssignLists(const std::vector<SearchPlan>& plans, const std::vector<Blob>& full_frame_blobs,
                   const std::vector<std::vector<Blob>>& window_blobs, ClassesFrame* frame) const;
  void SearchWindows(int64_t utime, ClassesFrame* frame) const;
  void FindCandidates(const std::vector<Blob>& full_frame_blobs, const ClassesFrame& frame,
                      LookAlikes* group) const;
  void Reacquire(int64_t utime, LookAlikes* group, ClassesFrame* frame) const;
  void ResolveLookAlikes(const LookAlikes& group, ClassesFrame* frame) const;

  // UpdateByCode's stages, likewise.
  struct CodeFrame;
  void PoolBlobs(const std::vector<Blob>& full_frame_blobs,
                 const std::vector<std::vector<Blob>>& window_blobs, const ClipFlags& clip_flags,
                 CodeFrame* frame) const;
  void FindPairs(CodeFrame* frame);  // counts pairing_checks_
  void GatePairs(int64_t utime, CodeFrame* frame) const;
  void DecideByCode(size_t i, bool any_full, CodeFrame* frame);  // may set full_requested_
  void TakeLoneBlob(size_t i, CodeFrame* frame) const;

  struct Track {
    TrackState state = TrackState::kSearching;
    int64_t last_seen_utime = 0;
    double u_px = 0.0, v_px = 0.0;                // last confirmed position
    double radius_px = 0.0;                       // its position blob's radius
    double du_px_per_s = 0.0, dv_px_per_s = 0.0;  // velocity estimate
    bool has_velocity = false;
    bool ever_found = false;
    bool found_last_update = false;  // consecutive finds give a velocity
    bool window_missed = false;      // last window search missed: full frame next
    bool has_hint = false;
    double hint_u_px = 0.0, hint_v_px = 0.0, hint_radius_px = 0.0;
    int64_t hint_utime = 0;
  };
  std::vector<TrackedRobotSpec> robots_;
  TrackerOptions options_;
  int width_px_;
  int height_px_;
  std::vector<Track> tracks_;
  int64_t pairing_checks_ = 0;
  // Updates since the last one with a full-frame search (-1: none yet).
  int updates_since_full_ = -1;
  // A robot out of view showed its code in a window: search in full next.
  bool full_requested_ = false;
};

}  // namespace roomfix::vision

#endif  // ROOMFIX_CORE_VISION_ROBOT_TRACKER_H_
