#include "core/vision/robot_tracker.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <utility>

namespace roomfix::vision {
namespace {

// Weight of the newest measured velocity in the smoothed estimate.
constexpr double kVelocityAlpha = 0.5;
// Two blobs of one class closer than this are the same blob (the same
// marker handed in both from a window and from the full frame).
constexpr double kSameBlobPx = 1.0;

double Seconds(int64_t from_utime, int64_t to_utime) {
  return std::max(0.0, static_cast<double>(to_utime - from_utime) * 1e-6);
}

double Distance(double u0, double v0, double u1, double v1) { return std::hypot(u1 - u0, v1 - v0); }

bool Inside(const cv::Rect& r, const Blob& b) {
  return b.u_px >= r.x && b.u_px < r.x + r.width && b.v_px >= r.y && b.v_px < r.y + r.height;
}

std::string Pixel(double u, double v) { return fmt::format("({:.1f}, {:.1f})", u, v); }

// Whether the clip reach around `b` (TrackerOptions::clip_radius_factor)
// leaves `area`. Pixel centres are integers, so a rectangle of pixels spans
// [x - 0.5, x + width - 0.5] and likewise in v.
bool ReachesEdge(const Blob& b, const cv::Rect& area, double factor, double margin_px) {
  const double reach = factor * b.radius_px + margin_px;
  return b.u_px - reach < area.x - 0.5 || b.u_px + reach > area.x + area.width - 0.5 ||
         b.v_px - reach < area.y - 0.5 || b.v_px + reach > area.y + area.height - 0.5;
}

// The rectangle each window list was searched in (the image for a list no
// window plan owns). `window_blobs` holds one list per plan, or one per
// window plan (a plan with a window) in order.
std::vector<cv::Rect> ListAreas(const std::vector<SearchPlan>& plans, size_t lists,
                                const cv::Rect& image) {
  std::vector<cv::Rect> areas(lists, image);
  const bool per_plan = lists == plans.size();
  size_t next = 0;
  for (size_t p = 0; p < plans.size(); ++p) {
    if (plans[p].full_frame || (!per_plan && plans[p].window.empty())) continue;
    const size_t k = per_plan ? p : next++;
    if (k < lists) areas[k] = plans[p].window;
  }
  return areas;
}

// Blobs already given to a robot in this frame.
class Taken {
 public:
  bool Contains(const Blob& b) const {
    return std::any_of(blobs_.begin(), blobs_.end(), [&](const Blob& t) {
      return t.class_index == b.class_index &&
             Distance(t.u_px, t.v_px, b.u_px, b.v_px) < kSameBlobPx;
    });
  }
  void Add(const Blob& b) { blobs_.push_back(b); }

 private:
  std::vector<Blob> blobs_;
};

// A position marker with its heading marker (if any) paired.
struct Candidate {
  Blob position;
  bool has_heading = false;
  Blob heading;
};

// Nearest free heading-class blob within `reach_px` of `position`.
bool PairHeading(const Blob& position, int heading_class, double reach_px,
                 const std::vector<const Blob*>& blobs, const Taken& taken, Blob* heading) {
  double best = std::numeric_limits<double>::infinity();
  for (const Blob* b : blobs) {
    if (b->class_index != heading_class || taken.Contains(*b)) continue;
    const double d = Distance(position.u_px, position.v_px, b->u_px, b->v_px);
    if (d <= reach_px && d < best) {
      best = d;
      *heading = *b;
    }
  }
  return std::isfinite(best);
}

void Fill(const Candidate& c, RobotObservation* obs) {
  obs->found = true;
  obs->position = c.position;
  obs->has_heading = c.has_heading;
  if (c.has_heading) {
    obs->heading = c.heading;
    obs->image_angle_rad =
        std::atan2(c.heading.v_px - c.position.v_px, c.heading.u_px - c.position.u_px);
  }
}

// A pair of pool blobs whose classes are a robot's code (UpdateByCode).
struct CodePair {
  size_t position, heading, robot;
  bool in_gate = true;
  bool clipped = false;  // a blob of it reaches an edge: evidence only
};

}  // namespace

const char* TrackStateName(TrackState state) {
  switch (state) {
    case TrackState::kSearching:
      return "searching";
    case TrackState::kTracking:
      return "tracking";
    case TrackState::kAmbiguous:
      return "ambiguous";
    case TrackState::kLost:
      return "lost";
  }
  return "unknown";
}

bool TrackerOptions::IsValid(std::string* error) const {
  auto positive = [error](double value, const char* name) {
    if (value > 0.0 && std::isfinite(value)) return true;
    *error = std::string(name) + " must be positive";
    return false;
  };
  auto non_negative = [error](double value, const char* name) {
    if (value >= 0.0 && std::isfinite(value)) return true;
    *error = std::string(name) + " must not be negative";
    return false;
  };
  if (!positive(max_speed_px_per_s, "max_speed_px_per_s") ||
      !non_negative(window_margin_px, "window_margin_px") ||
      !non_negative(window_radius_factor, "window_radius_factor") ||
      !positive(heading_search_radii, "heading_search_radii") ||
      !positive(lost_after_s, "lost_after_s") || !non_negative(hint_max_age_s, "hint_max_age_s") ||
      !positive(heading_offset_radii, "heading_offset_radii") ||
      !non_negative(heading_offset_tolerance, "heading_offset_tolerance") ||
      !non_negative(clip_margin_px, "clip_margin_px")) {
    return false;
  }
  if (absent_search_period_frames < 1 || absent_search_period_frames > 300) {
    *error = "absent_search_period_frames must lie in [1, 300]";
    return false;
  }
  if (max_blobs < 2) {
    *error = "max_blobs must be at least 2 (one robot's markers)";
    return false;
  }
  if (!(heading_offset_tolerance < 1.0)) {
    *error = "heading_offset_tolerance must lie in [0, 1)";
    return false;
  }
  if (!(heading_size_ratio > 0.0 && heading_size_ratio < 1.0)) {
    *error = "heading_size_ratio must lie in (0, 1)";
    return false;
  }
  // Below 1 a disc just inside the edge is not seen as touching it.
  if (!(clip_radius_factor >= 1.0) || !std::isfinite(clip_radius_factor)) {
    *error = "clip_radius_factor must be at least 1";
    return false;
  }
  return true;
}

RobotTracker::RobotTracker(std::vector<TrackedRobotSpec> robots, TrackerOptions options,
                           int width_px, int height_px)
    : robots_(std::move(robots)),
      options_(options),
      width_px_(width_px),
      height_px_(height_px),
      tracks_(robots_.size()) {}

std::vector<SearchPlan> RobotTracker::Plan(int64_t utime) const {
  std::vector<SearchPlan> plans;
  plans.reserve(robots_.size());
  const bool absent_due = updates_since_full_ < 0 || full_requested_ ||
                          updates_since_full_ + 1 >= options_.absent_search_period_frames;
  const cv::Rect image(0, 0, width_px_, height_px_);
  for (size_t i = 0; i < robots_.size(); ++i) {
    const TrackedRobotSpec& spec = robots_[i];
    const Track& t = tracks_[i];
    SearchPlan plan;
    plan.robot_id = spec.robot_id;
    if (t.state == TrackState::kTracking && !t.window_missed) {
      const double fixed =
          options_.window_margin_px + spec.position_radius_px * options_.window_radius_factor;
      // The window never needs to be larger than the image: cap dt there.
      const double max_half = 0.5 * std::max(width_px_, height_px_);
      double dt = Seconds(t.last_seen_utime, utime);
      if (options_.max_speed_px_per_s > 0.0) {
        dt = std::min(dt, std::max(0.0, (max_half - fixed) / options_.max_speed_px_per_s));
      }
      const double half = std::min(max_half, WindowHalfPx(i, dt));
      double u = t.u_px, v = t.v_px;
      if (t.has_velocity) {
        u += t.du_px_per_s * dt;
        v += t.dv_px_per_s * dt;
      }
      const int x0 = static_cast<int>(std::floor(u - half));
      const int y0 = static_cast<int>(std::floor(v - half));
      const int x1 = static_cast<int>(std::ceil(u + half)) + 1;
      const int y1 = static_cast<int>(std::ceil(v + half)) + 1;
      plan.window = cv::Rect(x0, y0, x1 - x0, y1 - y0) & image;
      plan.full_frame = plan.window.empty();
      if (plan.full_frame) plan.window = cv::Rect();
    } else if ((t.state == TrackState::kSearching || t.state == TrackState::kLost) && !absent_due) {
      plan.full_frame = false;  // out of view: no search in this frame
    }
    plans.push_back(plan);
  }
  // A full-frame search for one robot serves the others out of view.
  if (std::any_of(plans.begin(), plans.end(), [](const SearchPlan& p) { return p.full_frame; })) {
    for (SearchPlan& p : plans) {
      if (!p.full_frame && p.window.empty()) p.full_frame = true;
    }
  }
  return plans;
}

RobotTracker::ClipFlags RobotTracker::FindClipped(
    const std::vector<SearchPlan>& plans, const std::vector<Blob>& full_frame_blobs,
    const std::vector<std::vector<Blob>>& window_blobs) const {
  const cv::Rect image(0, 0, width_px_, height_px_);
  // In a frame with a full-frame search every marker is also measured whole
  // there (the pool keeps the larger measurement of one marker), so only the
  // image's edge cuts; without one, a window's edge cuts what it crosses.
  const bool any_full =
      std::any_of(plans.begin(), plans.end(), [](const SearchPlan& p) { return p.full_frame; });
  const std::vector<cv::Rect> areas = ListAreas(plans, window_blobs.size(), image);
  const double factor = options_.clip_radius_factor, margin = options_.clip_margin_px;
  const bool refuse = options_.refuse_clipped;
  ClipFlags flags;
  for (const Blob& b : full_frame_blobs) {
    flags.full.push_back(refuse && ReachesEdge(b, image, factor, margin));
  }
  flags.windows.resize(window_blobs.size());
  for (size_t k = 0; k < window_blobs.size(); ++k) {
    for (const Blob& b : window_blobs[k]) {
      flags.windows[k].push_back(refuse &&
                                 (ReachesEdge(b, image, factor, margin) ||
                                  (!any_full && ReachesEdge(b, areas[k], factor, margin))));
    }
  }
  return flags;
}

std::vector<RobotObservation> RobotTracker::Update(
    int64_t utime, const std::vector<SearchPlan>& plans, const std::vector<Blob>& full_frame_blobs,
    const std::vector<std::vector<Blob>>& window_blobs) {
  const bool any_full =
      std::any_of(plans.begin(), plans.end(), [](const SearchPlan& p) { return p.full_frame; });
  full_requested_ = false;
  std::vector<RobotObservation> obs = Identify(utime, plans, full_frame_blobs, window_blobs);
  updates_since_full_ = any_full ? 0 : updates_since_full_ + 1;
  return obs;
}

std::vector<RobotObservation> RobotTracker::Identify(
    int64_t utime, const std::vector<SearchPlan>& plans, const std::vector<Blob>& full_frame_blobs,
    const std::vector<std::vector<Blob>>& window_blobs) {
  pairing_checks_ = 0;
  size_t handed_in = full_frame_blobs.size();
  for (const auto& list : window_blobs) handed_in += list.size();
  if (handed_in > static_cast<size_t>(options_.max_blobs)) {
    // Too cluttered to judge: no identity at all rather than a guess on part
    // of the evidence, and none of the quadratic work.
    const size_t n = robots_.size();
    std::vector<RobotObservation> obs(n);
    for (size_t i = 0; i < n; ++i) {
      obs[i].robot_id = robots_[i].robot_id;
      obs[i].identity_problem = "too_many_blobs";
      obs[i].note = std::to_string(handed_in) + " blobs in the frame, over the limit of " +
                    std::to_string(options_.max_blobs) + ": no robot identified";
    }
    const bool any_full =
        std::any_of(plans.begin(), plans.end(), [](const SearchPlan& p) { return p.full_frame; });
    Bookkeep(utime, std::vector<bool>(n, any_full), std::vector<bool>(n, false), &obs);
    return obs;
  }
  const ClipFlags clipped = FindClipped(plans, full_frame_blobs, window_blobs);
  if (options_.identify_by_code) {
    return UpdateByCode(utime, plans, full_frame_blobs, window_blobs, clipped);
  }
  // By classes: a clipped blob is left out before anything is decided, so
  // a cut position marker is not found (its centroid is biased, and beside
  // a robot of the swapped classes its size could not tell the roles) and a
  // cut heading marker leaves the pose degraded.
  std::vector<Blob> full_kept;
  std::vector<std::vector<Blob>> windows_kept(window_blobs.size());
  std::set<int> clipped_classes;
  for (size_t k = 0; k < full_frame_blobs.size(); ++k) {
    if (clipped.full[k]) {
      clipped_classes.insert(full_frame_blobs[k].class_index);
    } else {
      full_kept.push_back(full_frame_blobs[k]);
    }
  }
  for (size_t w = 0; w < window_blobs.size(); ++w) {
    for (size_t k = 0; k < window_blobs[w].size(); ++k) {
      if (clipped.windows[w][k]) {
        clipped_classes.insert(window_blobs[w][k].class_index);
      } else {
        windows_kept[w].push_back(window_blobs[w][k]);
      }
    }
  }
  std::vector<RobotObservation> obs = UpdateByClasses(utime, plans, full_kept, windows_kept);
  for (size_t i = 0; i < obs.size(); ++i) {
    if (obs[i].found || clipped_classes.count(robots_[i].position_class) == 0) continue;
    obs[i].identity_problem = "marker_clipped";
    obs[i].note += std::string(obs[i].note.empty() ? "" : "; ") + "a class " +
                   std::to_string(robots_[i].position_class) +
                   " blob cut by the image's or a window's edge is not taken";
  }
  return obs;
}

bool RobotTracker::RecentlyFound(size_t i, int64_t utime) const {
  const Track& t = tracks_[i];
  return t.ever_found && Seconds(t.last_seen_utime, utime) < options_.lost_after_s;
}

void RobotTracker::Predict(size_t i, int64_t utime, double* u_px, double* v_px) const {
  const Track& t = tracks_[i];
  const double dt = Seconds(t.last_seen_utime, utime);
  *u_px = t.u_px + (t.has_velocity ? t.du_px_per_s * dt : 0.0);
  *v_px = t.v_px + (t.has_velocity ? t.dv_px_per_s * dt : 0.0);
}

double RobotTracker::WindowHalfPx(size_t i, double dt_s) const {
  return options_.window_margin_px + robots_[i].position_radius_px * options_.window_radius_factor +
         options_.max_speed_px_per_s * dt_s;
}

std::string RobotTracker::OutOfViewNote() const {
  return "out of view: looked for by a full-frame search every " +
         std::to_string(options_.absent_search_period_frames) + " frames";
}

// UpdateByClasses' working state within one frame.
struct RobotTracker::ClassesFrame {
  explicit ClassesFrame(size_t n) : obs(n), plan_of(n), blobs_of(n), ambiguous(n, false) {}
  std::vector<RobotObservation> obs;
  // Per robot: its plan (default full frame) and the blobs it may look at.
  std::vector<SearchPlan> plan_of;
  std::vector<std::vector<const Blob*>> blobs_of;
  Taken taken;  // blobs given to a robot so far: robots never share one
  std::vector<bool> ambiguous;
};

// Robots with one class pair that were all searched in the full frame, and
// the candidates they compete for.
struct RobotTracker::LookAlikes {
  std::pair<int, int> classes;  // position, heading
  std::vector<size_t> members;  // robot indices, in spec order
  std::vector<Candidate> candidates;
  std::vector<bool> candidate_taken;
  std::vector<bool> member_done;  // re-acquired (Reacquire)
  // "; class C blob(s) at ... have no heading marker beside them: not a
  // robot", or empty.
  std::string rejected_note;
};

std::vector<RobotObservation> RobotTracker::UpdateByClasses(
    int64_t utime, const std::vector<SearchPlan>& plans, const std::vector<Blob>& full_frame_blobs,
    const std::vector<std::vector<Blob>>& window_blobs) {
  const size_t n = robots_.size();
  ClassesFrame frame(n);
  AssignLists(plans, full_frame_blobs, window_blobs, &frame);
  SearchWindows(utime, &frame);

  // 2. Full-frame searches, grouped by class pair: robots that look alike
  // compete for the same candidates.
  std::map<std::pair<int, int>, std::vector<size_t>> groups;
  for (size_t i = 0; i < n; ++i) {
    if (frame.plan_of[i].full_frame) {
      groups[{robots_[i].position_class, robots_[i].heading_class}].push_back(i);
    }
  }
  for (auto& [pair, members] : groups) {
    LookAlikes group;
    group.classes = pair;
    group.members = std::move(members);
    FindCandidates(full_frame_blobs, frame, &group);
    Reacquire(utime, &group, &frame);
    ResolveLookAlikes(group, &frame);
  }

  std::vector<bool> full_plan(n);
  for (size_t i = 0; i < n; ++i) full_plan[i] = frame.plan_of[i].full_frame;
  Bookkeep(utime, full_plan, frame.ambiguous, &frame.obs);
  return std::move(frame.obs);
}

// Which blob lists a robot may look at: the window list of its plan (one
// list per plan, or one per window plan, as Update documents) and every
// full-frame blob, since a full-frame search run for another robot covers
// this one's window too. A plan naming no robot of the specs is ignored.
void RobotTracker::AssignLists(const std::vector<SearchPlan>& plans,
                               const std::vector<Blob>& full_frame_blobs,
                               const std::vector<std::vector<Blob>>& window_blobs,
                               ClassesFrame* frame) const {
  const size_t n = robots_.size();
  const bool per_plan_lists = window_blobs.size() == plans.size();
  size_t next_window_list = 0;
  std::map<int, size_t> index_of_id;
  for (size_t i = 0; i < n; ++i) index_of_id[robots_[i].robot_id] = i;
  for (size_t p = 0; p < plans.size(); ++p) {
    const std::vector<Blob>* list = nullptr;
    if (!plans[p].full_frame && (per_plan_lists || !plans[p].window.empty())) {
      const size_t k = per_plan_lists ? p : next_window_list++;
      if (k < window_blobs.size()) list = &window_blobs[k];
    }
    auto it = index_of_id.find(plans[p].robot_id);
    if (it == index_of_id.end()) continue;
    const size_t i = it->second;
    frame->plan_of[i] = plans[p];
    if (list != nullptr) {
      for (const Blob& b : *list) frame->blobs_of[i].push_back(&b);
    }
  }
  for (size_t i = 0; i < n; ++i) {
    frame->obs[i].robot_id = robots_[i].robot_id;
    for (const Blob& b : full_frame_blobs) frame->blobs_of[i].push_back(&b);
  }
}

// 1. Window searches: each robot with a window takes the position-class blob
// inside it nearest its prediction, nearest first across all robots, so two
// robots with the same classes cannot take one blob (the one predicted
// nearer wins, the other misses and gets a full-frame search next frame).
// A blob outside the window is never taken, so a look-alike elsewhere cannot
// steal the track. The heading marker is the nearest free heading-class
// blob within heading_search_radii; without one the pose is degraded.
void RobotTracker::SearchWindows(int64_t utime, ClassesFrame* frame) const {
  const size_t n = robots_.size();
  std::vector<RobotObservation>& obs = frame->obs;
  struct Option {
    double distance;
    size_t robot;
    const Blob* blob;
  };
  std::vector<Option> options;
  for (size_t i = 0; i < n; ++i) {
    if (frame->plan_of[i].full_frame) continue;
    double predicted_u = 0.0, predicted_v = 0.0;
    Predict(i, utime, &predicted_u, &predicted_v);
    int inside = 0;
    for (const Blob* b : frame->blobs_of[i]) {
      if (b->class_index != robots_[i].position_class || !Inside(frame->plan_of[i].window, *b)) {
        continue;
      }
      ++inside;
      options.push_back({Distance(predicted_u, predicted_v, b->u_px, b->v_px), i, b});
    }
    obs[i].num_candidates = inside;
  }
  std::stable_sort(options.begin(), options.end(),
                   [](const Option& a, const Option& b) { return a.distance < b.distance; });
  std::vector<bool> done(n, false);
  std::vector<Candidate> chosen(n);
  for (const Option& o : options) {
    if (done[o.robot] || frame->taken.Contains(*o.blob)) continue;
    done[o.robot] = true;
    frame->taken.Add(*o.blob);
    chosen[o.robot].position = *o.blob;
  }
  for (size_t i = 0; i < n; ++i) {
    if (frame->plan_of[i].full_frame) continue;
    if (done[i]) {
      const TrackedRobotSpec& spec = robots_[i];
      Candidate& c = chosen[i];
      c.has_heading = PairHeading(c.position, spec.heading_class,
                                  options_.heading_search_radii * spec.position_radius_px,
                                  frame->blobs_of[i], frame->taken, &c.heading);
      if (c.has_heading) frame->taken.Add(c.heading);
      Fill(c, &obs[i]);
      if (!c.has_heading) obs[i].note = "no heading marker beside the position marker";
    } else if (frame->plan_of[i].window.empty()) {
      obs[i].note = OutOfViewNote();
    } else {
      const cv::Rect& w = frame->plan_of[i].window;
      obs[i].note = "no free class " + std::to_string(robots_[i].position_class) +
                    " blob in the window at (" + std::to_string(w.x) + ", " + std::to_string(w.y) +
                    ") size " + std::to_string(w.width) + "x" + std::to_string(w.height) +
                    "; full-frame search next frame";
    }
  }
}

// A look-alike group's candidates in the full frame: free position-class
// blobs with a free heading-class blob within heading_search_radii (of the
// first member's radius). A lone position-class blob is not a robot (a
// coloured object on the floor): it is named in the note, not taken.
void RobotTracker::FindCandidates(const std::vector<Blob>& full_frame_blobs,
                                  const ClassesFrame& frame, LookAlikes* group) const {
  const Taken& taken = frame.taken;
  const auto& [position_class, heading_class] = group->classes;
  const TrackedRobotSpec& spec0 = robots_[group->members[0]];
  std::vector<const Blob*> blobs;
  for (const Blob& b : full_frame_blobs) blobs.push_back(&b);
  std::string rejected;
  for (const Blob* b : blobs) {
    if (b->class_index != position_class || taken.Contains(*b)) continue;
    Candidate c;
    c.position = *b;
    const double reach = options_.heading_search_radii * spec0.position_radius_px;
    c.has_heading = PairHeading(*b, heading_class, reach, blobs, taken, &c.heading);
    if (c.has_heading) {
      group->candidates.push_back(c);
    } else {
      rejected += (rejected.empty() ? "" : ", ") + Pixel(b->u_px, b->v_px);
    }
  }
  group->rejected_note = rejected.empty()
                             ? ""
                             : "; class " + std::to_string(position_class) + " blob(s) at " +
                                   rejected + " have no heading marker beside them: not a robot";
  group->candidate_taken.assign(group->candidates.size(), false);
}

// Re-acquisition after a brief occlusion, or by another sensor's hint: a
// member takes the candidate that is the only one within reach of where it
// should be (its last find when less than lost_after_s ago, reach
// window_margin_px + max_speed_px_per_s * dt; else a fresh hint and its
// radius); nearest first across members. Two candidates within reach leave
// the member to ResolveLookAlikes, which calls it ambiguous.
void RobotTracker::Reacquire(int64_t utime, LookAlikes* group, ClassesFrame* frame) const {
  const std::vector<size_t>& members = group->members;
  const std::vector<Candidate>& candidates = group->candidates;
  std::vector<std::pair<double, std::pair<size_t, size_t>>> recent;
  for (size_t m = 0; m < members.size(); ++m) {
    const size_t i = members[m];
    const Track& t = tracks_[i];
    double ref_u = 0.0, ref_v = 0.0, reach = 0.0;
    if (RecentlyFound(i, utime)) {
      ref_u = t.u_px;
      ref_v = t.v_px;
      reach = options_.window_margin_px +
              options_.max_speed_px_per_s * Seconds(t.last_seen_utime, utime);
    } else if (t.has_hint && std::abs(Seconds(t.hint_utime, utime)) <= options_.hint_max_age_s) {
      ref_u = t.hint_u_px;
      ref_v = t.hint_v_px;
      reach = t.hint_radius_px;
    } else {
      continue;
    }
    int within = 0;
    size_t which = 0;
    for (size_t k = 0; k < candidates.size(); ++k) {
      const double d =
          Distance(ref_u, ref_v, candidates[k].position.u_px, candidates[k].position.v_px);
      if (d <= reach) {
        ++within;
        which = k;
      }
    }
    if (within == 1) {
      recent.push_back(
          {Distance(ref_u, ref_v, candidates[which].position.u_px, candidates[which].position.v_px),
           {m, which}});
    }
  }
  std::sort(recent.begin(), recent.end());
  group->member_done.assign(members.size(), false);
  for (const auto& [d, mk] : recent) {
    const auto [m, k] = mk;
    if (group->member_done[m] || group->candidate_taken[k]) continue;
    group->member_done[m] = true;
    group->candidate_taken[k] = true;
    const size_t i = members[m];
    RobotObservation& o = frame->obs[i];
    Fill(candidates[k], &o);
    o.num_candidates = static_cast<int>(candidates.size());
    if (candidates.size() > 1) {
      o.note = std::string(RecentlyFound(i, utime) ? "re-acquired near the last position"
                                                   : "chosen by the position hint") +
               " among " + std::to_string(candidates.size()) + " candidates";
    }
    frame->taken.Add(candidates[k].position);
    frame->taken.Add(candidates[k].heading);
  }
}

// The members not re-acquired share the candidates left. One member and one
// candidate: taken. More candidates, or look-alike members of which one was
// found before: kAmbiguous, never a guess (a wrong identity is worse than
// none). Look-alikes that were never found, with a single candidate in view:
// the robots enter the view one at a time in spec order, so it is the first
// of them; the others find nothing left.
void RobotTracker::ResolveLookAlikes(const LookAlikes& group, ClassesFrame* frame) const {
  const auto& [position_class, heading_class] = group.classes;
  std::vector<size_t> open_members;
  for (size_t m = 0; m < group.members.size(); ++m) {
    if (!group.member_done[m]) open_members.push_back(group.members[m]);
  }
  std::vector<size_t> open_candidates;
  std::string positions;
  for (size_t k = 0; k < group.candidates.size(); ++k) {
    if (group.candidate_taken[k]) continue;
    open_candidates.push_back(k);
    positions += (positions.empty() ? "" : ", ") +
                 Pixel(group.candidates[k].position.u_px, group.candidates[k].position.v_px);
  }
  const int count = static_cast<int>(open_candidates.size());
  const bool none_found_before = std::none_of(open_members.begin(), open_members.end(),
                                              [&](size_t j) { return tracks_[j].ever_found; });
  const std::string& rejected_note = group.rejected_note;
  bool single_given = false;
  for (size_t i : open_members) {
    RobotObservation& o = frame->obs[i];
    if (single_given) {
      o.num_candidates = 0;
      o.note = "the only candidate went to robot " +
               std::to_string(robots_[open_members[0]].robot_id) +
               ", first in spec order of the robots with these marker classes";
      continue;
    }
    o.num_candidates = count;
    if (count == 0) {
      o.note = "no class " + std::to_string(position_class) + " blob with a class " +
               std::to_string(heading_class) + " heading marker beside it in the full frame" +
               rejected_note;
    } else if (open_members.size() > 1 && !(count == 1 && none_found_before)) {
      std::string ids;
      for (size_t j : open_members) {
        ids += (ids.empty() ? "" : ", ") + std::to_string(robots_[j].robot_id);
      }
      frame->ambiguous[i] = true;
      o.note = "robots " + ids + " share marker classes " + std::to_string(position_class) + "/" +
               std::to_string(heading_class) + ": " + std::to_string(count) + " candidate(s) at " +
               positions + ", cannot tell which robot is which" + rejected_note;
    } else if (count > 1) {
      frame->ambiguous[i] = true;
      o.note = std::to_string(count) + " candidates with a heading marker beside them at " +
               positions + rejected_note;
    } else {
      const Candidate& c = group.candidates[open_candidates[0]];
      Fill(c, &o);
      o.note = rejected_note.empty() ? "" : rejected_note.substr(2);
      frame->taken.Add(c.position);
      frame->taken.Add(c.heading);
      single_given = true;
    }
  }
}

void RobotTracker::Bookkeep(int64_t utime, const std::vector<bool>& full_plan,
                            const std::vector<bool>& ambiguous,
                            std::vector<RobotObservation>* observations) {
  std::vector<RobotObservation>& obs = *observations;
  for (size_t i = 0; i < robots_.size(); ++i) {
    Track& t = tracks_[i];
    RobotObservation& o = obs[i];
    if (o.found) {
      const double u = o.position.u_px;
      const double v = o.position.v_px;
      const double dt = Seconds(t.last_seen_utime, utime);
      if (full_plan[i] && !t.found_last_update) {
        t.has_velocity = false;  // a re-acquisition: the old motion is stale
      } else if (t.found_last_update && dt > 0.0) {
        const double du = (u - t.u_px) / dt;
        const double dv = (v - t.v_px) / dt;
        if (t.has_velocity) {
          t.du_px_per_s = kVelocityAlpha * du + (1.0 - kVelocityAlpha) * t.du_px_per_s;
          t.dv_px_per_s = kVelocityAlpha * dv + (1.0 - kVelocityAlpha) * t.dv_px_per_s;
        } else {
          t.du_px_per_s = du;
          t.dv_px_per_s = dv;
          t.has_velocity = true;
        }
      }
      if (!t.has_velocity) {
        t.du_px_per_s = 0.0;
        t.dv_px_per_s = 0.0;
      }
      t.u_px = u;
      t.v_px = v;
      t.radius_px = o.position.radius_px;
      t.last_seen_utime = utime;
      t.ever_found = true;
      t.found_last_update = true;
      t.window_missed = false;
      t.state = TrackState::kTracking;
    } else {
      t.found_last_update = false;
      t.window_missed = true;
      if (ambiguous[i]) {
        t.state = TrackState::kAmbiguous;
      } else if (!t.ever_found) {
        t.state = TrackState::kSearching;
      } else if (Seconds(t.last_seen_utime, utime) >= options_.lost_after_s) {
        t.state = TrackState::kLost;
        t.has_velocity = false;
      } else {
        t.state = TrackState::kTracking;
      }
    }
    o.state = t.state;
  }
}

// UpdateByCode's working state within one frame.
struct RobotTracker::CodeFrame {
  explicit CodeFrame(size_t n)
      : obs(n),
        gated(n, false),
        gate_u(n),
        gate_v(n),
        gate_px(n),
        inside(n, 0),
        outside(n, 0),
        clipped_inside(n, 0),
        interleaved(n, false),
        ambiguous(n, false) {}
  std::vector<RobotObservation> obs;
  // Every blob searched, once, and whether it is clipped (PoolBlobs).
  std::vector<Blob> pool;
  std::vector<bool> clipped;
  std::vector<CodePair> pairs;
  // Bounds of a heading blob's radius over its position blob's (FindPairs).
  double ratio_lo = 0.0, ratio_hi = 0.0;
  // Per robot: whether it has a gate (found less than lost_after_s ago),
  // its centre and radius, and its code's pairs inside and outside it.
  std::vector<bool> gated;
  std::vector<double> gate_u, gate_v, gate_px;
  std::vector<int> inside, outside, clipped_inside;
  std::vector<bool> interleaved;
  // Pool blobs that a whole pair inside its gate claims.
  std::vector<bool> in_a_pair;
  std::vector<bool> ambiguous;
};

std::vector<RobotObservation> RobotTracker::UpdateByCode(
    int64_t utime, const std::vector<SearchPlan>& plans, const std::vector<Blob>& full_frame_blobs,
    const std::vector<std::vector<Blob>>& window_blobs, const ClipFlags& clip_flags) {
  const size_t n = robots_.size();
  CodeFrame frame(n);
  PoolBlobs(full_frame_blobs, window_blobs, clip_flags, &frame);
  std::vector<bool> full_plan(n, true);
  for (const SearchPlan& p : plans) {
    for (size_t i = 0; i < n; ++i) {
      if (robots_[i].robot_id == p.robot_id) full_plan[i] = p.full_frame;
    }
  }
  FindPairs(&frame);
  GatePairs(utime, &frame);
  const bool any_full =
      std::any_of(plans.begin(), plans.end(), [](const SearchPlan& p) { return p.full_frame; });
  for (size_t i = 0; i < n; ++i) DecideByCode(i, any_full, &frame);
  Bookkeep(utime, full_plan, frame.ambiguous, &frame.obs);
  return std::move(frame.obs);
}

// Every blob searched, once. Windows are searched for every class, so a
// neighbour's marker that a window's edge cuts shows there as a smaller blob
// a few pixels off the whole one (measured in its own window or the full
// frame): two blobs of one class whose centres lie within the larger one's
// radius are one marker, and a whole measurement is kept over a clipped one,
// else the larger. Quadratic in the blobs, which max_blobs bounds.
void RobotTracker::PoolBlobs(const std::vector<Blob>& full_frame_blobs,
                             const std::vector<std::vector<Blob>>& window_blobs,
                             const ClipFlags& clip_flags, CodeFrame* frame) const {
  std::vector<Blob>& pool = frame->pool;
  std::vector<bool>& clipped = frame->clipped;
  auto add = [&pool, &clipped](const Blob& b, bool b_clipped) {
    for (size_t k = 0; k < pool.size(); ++k) {
      Blob& p = pool[k];
      if (p.class_index == b.class_index && Distance(p.u_px, p.v_px, b.u_px, b.v_px) <
                                                std::max({p.radius_px, b.radius_px, kSameBlobPx})) {
        if (clipped[k] != b_clipped ? clipped[k] : b.area_px > p.area_px) {
          p = b;
          clipped[k] = b_clipped;
        }
        return;
      }
    }
    pool.push_back(b);
    clipped.push_back(b_clipped);
  };
  for (size_t w = 0; w < window_blobs.size(); ++w) {
    for (size_t k = 0; k < window_blobs[w].size(); ++k) {
      add(window_blobs[w][k], clip_flags.windows[w][k]);
    }
  }
  for (size_t k = 0; k < full_frame_blobs.size(); ++k) {
    add(full_frame_blobs[k], clip_flags.full[k]);
  }
}

// Pairs whose code is a robot's. Size: the heading blob's radius over the
// position blob's lies nearer the code's ratio rho than 1 in log scale,
// i.e. in (rho^1.5, rho^0.5) (0.35..0.71 for rho 0.5): the geometric
// midpoints to a same-size pair and to a pair one step smaller still.
// Distance: heading_offset_radii position radii within
// heading_offset_tolerance. Counts the comparisons in pairing_checks_.
void RobotTracker::FindPairs(CodeFrame* frame) {
  const std::vector<Blob>& pool = frame->pool;
  std::map<std::pair<int, int>, size_t> robot_of_code;
  for (size_t i = 0; i < robots_.size(); ++i) {
    robot_of_code[{robots_[i].position_class, robots_[i].heading_class}] = i;
  }
  const double rho = options_.heading_size_ratio;
  frame->ratio_lo = std::pow(rho, 1.5);
  frame->ratio_hi = std::sqrt(rho);
  const double ratio_lo = frame->ratio_lo, ratio_hi = frame->ratio_hi;
  const double offset_lo =
      options_.heading_offset_radii * (1.0 - options_.heading_offset_tolerance);
  const double offset_hi =
      options_.heading_offset_radii * (1.0 + options_.heading_offset_tolerance);
  // A sweep along u: a heading blob lies within offset_hi position radii of
  // its position blob, so only blobs in that band of u are compared. Blobs
  // of a frame do not overlap, which bounds how many fit in the band.
  std::vector<size_t> by_u(pool.size());
  for (size_t k = 0; k < pool.size(); ++k) by_u[k] = k;
  std::sort(by_u.begin(), by_u.end(), [&pool](size_t x, size_t y) {
    return pool[x].u_px < pool[y].u_px || (pool[x].u_px == pool[y].u_px && x < y);
  });
  for (size_t a = 0; a < pool.size(); ++a) {
    const Blob& p = pool[a];
    if (!(p.radius_px > 0.0)) continue;
    const double reach = offset_hi * p.radius_px;
    auto first = std::lower_bound(by_u.begin(), by_u.end(), p.u_px - reach,
                                  [&pool](size_t k, double u) { return pool[k].u_px < u; });
    for (auto it_b = first; it_b != by_u.end() && pool[*it_b].u_px <= p.u_px + reach; ++it_b) {
      const size_t b = *it_b;
      const Blob& h = pool[b];
      if (a == b) continue;
      ++pairing_checks_;
      const auto it = robot_of_code.find({p.class_index, h.class_index});
      if (it == robot_of_code.end()) continue;
      const double ratio = h.radius_px / p.radius_px;
      const double offset = Distance(p.u_px, p.v_px, h.u_px, h.v_px) / p.radius_px;
      if (ratio > ratio_lo && ratio < ratio_hi && offset >= offset_lo && offset <= offset_hi) {
        frame->pairs.push_back({a, b, it->second, true, frame->clipped[a] || frame->clipped[b]});
      }
    }
  }
}

// Gates: where a recently found robot can be now (its prediction, and the
// tracking window's half-size as radius). Counts each robot's pairs inside
// and outside its gate (a robot without a gate has every pair inside), and
// marks robots whose in-gate pair shares a blob with another in-gate pair
// (markers of neighbours interleaved: no pairing can be trusted there).
void RobotTracker::GatePairs(int64_t utime, CodeFrame* frame) const {
  const size_t n = robots_.size();
  for (size_t i = 0; i < n; ++i) {
    if (!RecentlyFound(i, utime)) continue;
    frame->gated[i] = true;
    Predict(i, utime, &frame->gate_u[i], &frame->gate_v[i]);
    frame->gate_px[i] = WindowHalfPx(i, Seconds(tracks_[i].last_seen_utime, utime));
  }
  for (CodePair& pr : frame->pairs) {
    const size_t i = pr.robot;
    if (frame->gated[i]) {
      const Blob& p = frame->pool[pr.position];
      pr.in_gate =
          Distance(frame->gate_u[i], frame->gate_v[i], p.u_px, p.v_px) <= frame->gate_px[i];
    }
    ++(pr.in_gate ? frame->inside[i] : frame->outside[i]);
    if (pr.in_gate && pr.clipped) ++frame->clipped_inside[i];
  }
  std::vector<int> uses(frame->pool.size(), 0);
  for (const CodePair& pr : frame->pairs) {
    if (!pr.in_gate) continue;
    ++uses[pr.position];
    ++uses[pr.heading];
  }
  for (const CodePair& pr : frame->pairs) {
    if (pr.in_gate && (uses[pr.position] > 1 || uses[pr.heading] > 1)) {
      frame->interleaved[pr.robot] = true;
    }
  }
  // Blobs a whole pair claims (a clipped pair's whole blob may still be a
  // robot's lone position marker: TakeLoneBlob).
  frame->in_a_pair.assign(frame->pool.size(), false);
  for (const CodePair& pr : frame->pairs) {
    if (!pr.in_gate || pr.clipped) continue;
    frame->in_a_pair[pr.position] = true;
    frame->in_a_pair[pr.heading] = true;
  }
}

// Robot i's verdict from its code's pairs, by the rules UpdateByCode's
// declaration states. A robot out of view until now, in a frame searched in
// windows only, is never identified: a code is unique only if the whole
// frame shows it once (a sighting in another robot's window asks for a
// full-frame search next frame).
void RobotTracker::DecideByCode(size_t i, bool any_full, CodeFrame* frame) {
  RobotObservation& o = frame->obs[i];
  const int inside = frame->inside[i], outside = frame->outside[i];
  o.robot_id = robots_[i].robot_id;
  o.num_candidates = inside;
  if (!frame->gated[i] && !any_full) {
    if (inside > 0) {
      full_requested_ = true;
      o.note =
          "its code is seen in another robot's window: identified at the next full-frame "
          "search";
    } else {
      o.note = OutOfViewNote();
    }
    return;
  }
  if (frame->interleaved[i]) {
    frame->ambiguous[i] = true;
    o.identity_problem = "interleaved_markers";
    o.note = "a marker of its code pair also pairs with another robot's marker: not published";
    return;
  }
  if (inside >= 2) {
    frame->ambiguous[i] = true;
    o.identity_problem = "code_seen_twice";
    o.note = "its code is seen " + std::to_string(inside) + " times" +
             (frame->gated[i] ? " inside its gate" : "") + ": not published";
    return;
  }
  if (inside == 1 && frame->clipped_inside[i] == 0) {
    const auto pr = std::find_if(frame->pairs.begin(), frame->pairs.end(),
                                 [&](const CodePair& x) { return x.robot == i && x.in_gate; });
    Candidate c;
    c.position = frame->pool[pr->position];
    // Another pair with this code outside the gate: the identity rests on
    // the gate alone, so the heading (and the status ok) is withheld.
    c.has_heading = outside == 0;
    c.heading = frame->pool[pr->heading];
    Fill(c, &o);
    if (outside > 0) {
      o.identity_problem = "code_seen_twice";
      o.note = "its code is seen inside its gate and " + std::to_string(outside) +
               " time(s) outside: published degraded";
    }
    return;
  }
  if (inside == 1) {
    // Its only sighting is cut by an edge: a marker cut small can read as
    // the other role (a swapped pair's robot), and its centroid is off.
    o.identity_problem = "marker_clipped";
    o.note =
        "its code is seen only with a marker cut by the image's or a window's edge: "
        "not taken";
  } else if (outside > 0) {
    o.identity_problem = "impossible_jump";
    o.note = "its code is seen only beyond where it can be after its last find: not published";
    return;
  }
  if (!frame->gated[i]) {
    if (o.identity_problem.empty()) o.note = "no pair of blobs shows its marker code";
    return;
  }
  TakeLoneBlob(i, frame);
}

// No whole pair: a lone whole position-class blob of the last find's size
// (radius ratio within (ratio_hi, 1 / ratio_hi), so not a heading marker of
// another code) inside the gate, which no whole pair claims, is taken when
// it is the only one, degraded (no heading), as the demo does. Two or more
// are not told apart.
void RobotTracker::TakeLoneBlob(size_t i, CodeFrame* frame) const {
  RobotObservation& o = frame->obs[i];
  const double ratio_hi = frame->ratio_hi;
  int lone = 0;
  const Blob* taken = nullptr;
  for (size_t k = 0; k < frame->pool.size(); ++k) {
    const Blob& b = frame->pool[k];
    if (frame->in_a_pair[k] || frame->clipped[k] || b.class_index != robots_[i].position_class) {
      continue;
    }
    const double size = tracks_[i].radius_px > 0.0 ? b.radius_px / tracks_[i].radius_px : 1.0;
    if (size <= ratio_hi || size >= 1.0 / ratio_hi) continue;
    if (Distance(frame->gate_u[i], frame->gate_v[i], b.u_px, b.v_px) > frame->gate_px[i]) continue;
    ++lone;
    taken = &b;
  }
  const std::string clipped_note = o.identity_problem.empty() ? "" : o.note + "; ";
  if (lone == 1) {
    Candidate c;
    c.position = *taken;
    Fill(c, &o);
    o.note = clipped_note + "no heading marker beside the position marker";
  } else {
    o.note = clipped_note + (lone == 0 ? "no pair of blobs shows its code inside its gate"
                                       : std::to_string(lone) +
                                             " lone position-class blobs inside its gate: none "
                                             "taken");
  }
}

void RobotTracker::SetHint(int robot_id, double u_px, double v_px, double radius_px,
                           int64_t utime) {
  for (size_t i = 0; i < robots_.size(); ++i) {
    if (robots_[i].robot_id != robot_id) continue;
    Track& t = tracks_[i];
    t.has_hint = true;
    t.hint_u_px = u_px;
    t.hint_v_px = v_px;
    t.hint_radius_px = radius_px;
    t.hint_utime = utime;
  }
}

}  // namespace roomfix::vision
