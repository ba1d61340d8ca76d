#ifndef ROOMFIX_TOOLS_REPLAY_H_
#define ROOMFIX_TOOLS_REPLAY_H_

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "camera_proc/camera_node.h"
#include "core/calib/calibration_file.h"
#include "core/world/site.h"
#include "fusion_proc/fusion_node.h"
#include "msgio/channels.h"
#include "msgio/log.h"
#include "msgio/site_message.h"
#include "roomfix/process_status_t.hpp"
#include "trilat_proc/trilat_node.h"

namespace roomfix {

struct PipelineReplayOptions {
  // Which nodes run again. A re-run node's recorded outputs are left out of
  // the new log (they stay in the old one) and replaced by its new ones.
  bool trilat = true;
  bool fusion = true;
  // camera_proc's node from the recorded MARKER_PIXELS (CameraNode::
  // OnMarkerPixels): tracking, floor mapping and POSE_CAMERA, one node per
  // camera of the site with a calibration in camera_calibrations. The
  // frames themselves are not in logs; detection is not re-run.
  bool camera = false;
  // By camera id: the calibration each camera's node maps pixels with (the
  // log's SITE carries the files' texts; ReplayCameraCalibrations).
  std::map<int, calib::Calibration> camera_calibrations;
  CameraNodeOptions camera_options;
  // As trilat_proc's and fusion_proc's flags; the replay command's default
  // method is robust, which every shipped configuration runs.
  TrilatNodeOptions trilat_options;
  FusionNodeOptions fusion_options;
  // Re-derive every range of RANGES from the site, as zigbee_bridge would
  // have with it: the receiver's position, and the range from the recorded
  // time of flight and speed of sound minus the receiver's range offset
  // (radio::RangeFromTimeOfFlight). For a site that is not the one the log
  // was recorded with (new offsets from `roomfix survey`).
  bool restamp_ranges = false;
  // Ticks on a grid of log time, as RunLoop ticks a live node every 10 ms.
  int tick_period_ms = 10;
  // The site the new log carries, when it is not the recorded one (a site
  // file given on the command line): the recorded SITE events are left out
  // and this one is written at the first event's log time and every
  // kSitePeriodUs of log time after, as a live process publishes it, with
  // that time as its utime. Unset: the recorded SITE events are copied.
  std::optional<site_t> site_message;

  bool IsValid(std::string* error) const;
};

struct PipelineReplaySummary {
  // False when the run stopped: the log could not be read at all, or writing
  // the new log failed (`error` says which).
  bool ok = false;
  std::string error;
  int64_t events_read = 0;
  // Recorded events copied to the new log (and delivered to the nodes).
  int64_t inputs_written = 0;
  // Recorded events LCM's tools could not replay (LogWriter::Loggable: a
  // channel over 63 bytes...), left out of the new log and not delivered.
  int64_t inputs_not_loggable = 0;
  // Recorded outputs of the re-run nodes left out, by channel.
  std::map<std::string, int64_t> old_outputs_dropped;
  // What the re-run nodes published, by channel (STATUS as REPLAY_STATUS).
  std::map<std::string, int64_t> new_outputs;
  int64_t ranges_restamped = 0;
  // Ranges whose time of flight or speed of sound was not a usable number:
  // their position was restamped, their range kept as recorded.
  int64_t ranges_kept = 0;
  // Ranges from a receiver the site does not name: passed on as recorded,
  // for trilat to refuse (unknown_receiver). restamped + kept + this is
  // every range of every range set read.
  int64_t ranges_unknown_receiver = 0;
  // Events whose log time cannot be right (EventTimeScreen: farther than
  // kMaxEventTimeOffsetUs from the median of their neighbours): left out of
  // the new log, not delivered, and never moving the replay's clock.
  int64_t events_time_refused = 0;
  // Re-run nodes' heartbeats not written because the input since that
  // node's last written one was under kStatusRepeatInputRatio times its size
  // (a sparse log); each node's first heartbeat is always written.
  int64_t heartbeats_thinned = 0;
  int64_t ticks = 0;
  // Grid ticks not run because they fell in a gap longer than kMaxCatchUpUs.
  int64_t ticks_skipped = 0;
  // The first and last accepted event's log time.
  int64_t first_utime = 0;
  int64_t last_utime = 0;
  // The log's damage as LogReader counts it: every good event around it was
  // replayed.
  bool damaged = false;
  int64_t bytes_skipped = 0;
  int64_t damage_regions = 0;
  std::string damage;
  // Recorded messages the nodes refused before decoding (DecodeChecked), by
  // `<CHANNEL>.<reason>`: hostile or corrupt input, counted, not fatal.
  std::map<std::string, int64_t> refused;
  // The nodes' final heartbeats (counters, rejections), when they ran.
  process_status_t trilat_status{};
  process_status_t fusion_status{};
  // One per re-run camera node, in the site's camera order.
  std::vector<process_status_t> camera_status;
};

// Re-runs the chosen nodes (the classes trilat_proc, fusion_proc and
// camera_proc run)
// over a recorded log on the log's own time, and writes the recorded events
// (minus the re-run nodes' old outputs) and the new outputs to `out`.
//
// Time: every node's "now" is the log's. A recorded event is delivered with
// its log timestamp as receive time, and the nodes are ticked on a
// tick_period_ms grid of log time before each event; a gap longer than
// kMaxCatchUpUs is crossed with one tick at the new time (the rest counted
// in ticks_skipped), so neither a timestamp that jumps by a year nor a
// sparse log costs more than one tick per event. A new output is written with the log time at
// which it was published, after the event that caused it. Nothing reads the
// wall clock, so the output is a function of the input log and the options
// only: two runs give byte-identical logs.
//
// Bad input: damage is skipped by LogReader and counted; undecodable
// messages are refused by the bus and counted; neither stops the replay.
PipelineReplaySummary ReplayPipeline(LogReader* in, const Site& site,
                                     const PipelineReplayOptions& options, LogWriter* out);

// Where the replay's site comes from (docs/replay.md, "The site").
struct ReplaySite {
  LoadedSite loaded;
  // --site: a new site; the recorded ranges are re-derived from it.
  bool is_new = false;
  // Loaded from a file (--config or --site), so the new log carries it
  // (PipelineReplayOptions::site_message); else it is the log's own.
  bool from_file = false;
  // "site from LOG: demo_room, hash ..." or "site from --config PATH: ...".
  std::string used_line;
  // For --config: a mismatch with the log's site, naming the keys, and SITE
  // messages refused in the log. For --site the mismatch is the point: it is
  // in `notes`.
  std::vector<std::string> warnings;
  std::vector<std::string> notes;
};

// The site of a replay: --config (the recorded site; a warning names the
// keys where the log's own differs), --site (a new one), or neither: the
// log's SITE (ReadSiteFromLog). False with one line when both are given, a
// file does not load, or the log holds no usable SITE and neither is given.
bool ResolveReplaySite(const std::string& log_path, const std::string& config_path,
                       const std::string& new_site_path, ReplaySite* out, std::string* error);

// The SITE message the new log carries for a site from a file: published by
// "roomfix replay" on host "replay" with pid 0, so two replays are
// byte-identical.
bool MakeReplaySiteMessage(const LoadedSite& loaded, site_t* msg, std::string* error);

// The calibrations of the site's cameras, parsed from the texts the loaded
// site carries (from the log's SITE or read with the site file), by camera
// id; a camera without one is left out. False with one line when a text does
// not parse or is for another image size than the camera's.
bool ReplayCameraCalibrations(const LoadedSite& loaded, std::map<int, calib::Calibration>* out,
                              std::string* error);

// Whether the log holds at least one event on `channel` (--nodes camera
// needs MARKER_PIXELS). False with the reason when the log cannot be read.
bool LogHoldsChannel(const std::string& path, const std::string& channel, bool* holds,
                     std::string* error);

// The longest gap of log time the replay ticks through on its grid: three
// heartbeat periods (ProcessStatus::MaybePublish publishes every second), so
// a short pause is replayed as a live node lived it. Over a longer gap the
// nodes are ticked once, at the new event's time, and the grid ticks between
// are counted as skipped: a live node would only have repeated its heartbeat
// there, and replaying those heartbeats made a sparse log (events 20 s
// apart) grow some 300-fold.
inline constexpr int64_t kMaxCatchUpUs = 3'000'000;

// A repeat of the new SITE (PipelineReplayOptions::site_message) is written
// once kSitePeriodUs of log time has passed AND the input copied since the
// last one is at least this many times its size, so the site (kilobytes of
// text) never outweighs a sparse log: SITE bytes stay below 1/4 of the input
// plus the first copy.
inline constexpr int64_t kSiteRepeatInputRatio = 4;

// A re-run node's heartbeat is written once at least this many times its
// size of input (the input log's bytes, headers included) has been read
// since that node's last written heartbeat. The catch-up limit alone lets
// each node beat three times in a gap just under kMaxCatchUpUs: 20 000 empty
// events 2.99 s apart (586 KB) replayed into 20.3 MB (issue #28). With N
// nodes the heartbeats then add at most N / 2 times the input, plus one
// heartbeat per node. A live-rate log (kilobytes per second per node's
// ~300-byte heartbeat) is never thinned.
inline constexpr int64_t kStatusRepeatInputRatio = 2;

// An event whose log time cannot be right: more than this ahead of the
// median time of the kEventTimeNeighbours events after it, or more than this
// behind the last accepted event while the events after it do not follow it
// there. The logger stamps each event with its receive time in order, so a
// recorded log's times rise (a sparse log is never refused, however far
// apart its events), and a host clock step moves all the events after it
// together. Such an event is refused and counted (events_time_refused) and
// never moves the replay's clock: one event at INT64_MAX 10 % into the demo
// log changed 1 056 of its 1 170 fused poses, and placed first it stopped
// the heartbeats (issue #28). One second is a third of kMaxCatchUpUs and far
// above the logger's queueing jitter. The last event of a log has nothing
// after it to be judged against.
inline constexpr int64_t kMaxEventTimeOffsetUs = 1'000'000;
inline constexpr int kEventTimeNeighbours = 8;

// Reads a log's events through the time screen above.
class EventTimeScreen {
 public:
  explicit EventTimeScreen(LogReader* in) : in_(in) {}
  // The next event whose time is plausible; false at the end of the log.
  bool Next(LogEvent* event);
  int64_t refused() const { return refused_; }

 private:
  bool Plausible(int64_t utime) const;

  LogReader* in_;
  bool end_ = false;
  std::deque<LogEvent> ahead_;
  std::deque<int64_t> accepted_;  // the last kEventTimeNeighbours accepted
  int64_t refused_ = 0;
};

// The same run for a path: refuses `out_path` equal to `in_path` (the same
// file, also through a link) and an existing `out_path` unless overwrite.
PipelineReplaySummary ReplayPipelineFile(const std::string& in_path, const Site& site,
                                         const PipelineReplayOptions& options,
                                         const std::string& out_path, bool overwrite);

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_REPLAY_H_
