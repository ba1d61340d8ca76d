#include "tools/csv_export.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <utility>

#include "msgio/message_json.h"
#include "msgio/wire_check.h"
#include "roomfix/detector_view_request_t.hpp"
#include "roomfix/detector_view_t.hpp"
#include "roomfix/image_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "roomfix/site_t.hpp"

namespace roomfix {
namespace {

namespace fs = std::filesystem;

constexpr char kOtherChannels[] = "<other>";
constexpr char kRejectedPrefix[] = "rejected/";
constexpr char kCountersPrefix[] = "counters/";

// The enum names, indexed by the value: DecodeChecked has refused any value
// outside the .lcm constants (enum_out_of_range), so the index is in range.
constexpr const char* kSourceNames[] = {"unknown", "camera", "ultrasound", "fused", "ground_truth"};
static_assert(pose2d_t::SOURCE_GROUND_TRUTH == 4 && pose2d_t::SOURCE_FUSED == 3);
constexpr const char* kPoseStatusNames[] = {"ok", "degraded", "lost"};
static_assert(pose2d_t::STATUS_LOST == 2 && pose2d_t::STATUS_DEGRADED == 1);
constexpr const char* kRoleNames[] = {"none", "position", "heading"};
static_assert(marker_t::ROLE_HEADING == 2 && marker_t::ROLE_POSITION == 1);
constexpr const char* kSearchModeNames[] = {"full_frame", "region_of_interest"};
static_assert(marker_pixels_t::SEARCH_REGION_OF_INTEREST == 1);
constexpr const char* kStateNames[] = {"starting", "running", "degraded", "stopping", "failed"};
static_assert(process_status_t::STATE_FAILED == 4 && process_status_t::STATE_STOPPING == 3);

// Every file starts with the event's receive time and the message's own
// time, each as microseconds since the epoch and as seconds from the log's
// first event.
const std::vector<std::string> kTimeColumns = {"recv_utime", "recv_s", "utime", "utime_s"};

std::vector<std::string> WithTimes(std::vector<std::string> columns) {
  columns.insert(columns.begin(), kTimeColumns.begin(), kTimeColumns.end());
  return columns;
}

// One line of CSV, field by field. A hand-written writer, not a library:
// the one Debian CSV writer (libcsv3) only quotes a single field, so it
// would save these few lines at the price of a runtime dependency on every
// host; numbers are written with std::to_chars (shortest form that reads
// back to the same double, C locale whatever the user's).
class CsvLine {
 public:
  void Int(int64_t v) {
    Sep();
    char text[24];
    const auto end = std::to_chars(text, text + sizeof(text), v);
    line_.append(text, end.ptr);
  }
  // NaN and infinities are an empty field: pandas reads NaN, PlotJuggler
  // skips the point.
  void Real(double v) {
    Sep();
    if (!std::isfinite(v)) return;
    char text[32];
    const auto end = std::to_chars(text, text + sizeof(text), v);
    line_.append(text, end.ptr);
  }
  // Seconds from the log's start. Divided, not multiplied by 1e-6 (which
  // is not exact in binary): the quotient is the double nearest the
  // decimal, so 1003548 us prints as 1.003548, not 1.0035479999999999.
  void Seconds(int64_t utime, int64_t start_utime) {
    Real(static_cast<double>(utime - start_utime) / 1e6);
  }
  void Text(const std::string& v) {
    Sep();
    line_ += CsvField(v);
  }
  void Empty() { Sep(); }
  // The line with its end; the writer is then empty for the next.
  std::string Take() {
    line_ += '\n';
    first_ = true;
    return std::exchange(line_, std::string());
  }

 private:
  void Sep() {
    if (!first_) line_ += ',';
    first_ = false;
  }
  std::string line_;
  bool first_ = true;
};

std::string HeaderLine(const std::vector<std::string>& columns) {
  CsvLine line;
  for (const std::string& c : columns) line.Text(c);
  return line.Take();
}

void PutTimes(CsvLine* line, int64_t recv_utime, int64_t utime, int64_t start_utime) {
  line->Int(recv_utime);
  line->Seconds(recv_utime, start_utime);
  line->Int(utime);
  line->Seconds(utime, start_utime);
}

// The message types with a CSV, by LCM type name.
enum class Kind {
  kPose,
  kRanges,
  kMarkers,
  kStatus,
  kImage,
  kSite,
  kDetectorView,
  kDetectorViewRequest,
  kNone
};

Kind KindOf(const std::string& type_name) {
  if (type_name == "roomfix.pose2d_t") return Kind::kPose;
  if (type_name == "roomfix.range_set_t") return Kind::kRanges;
  if (type_name == "roomfix.marker_pixels_t") return Kind::kMarkers;
  if (type_name == "roomfix.process_status_t") return Kind::kStatus;
  if (type_name == "roomfix.image_t") return Kind::kImage;
  if (type_name == "roomfix.site_t") return Kind::kSite;
  if (type_name == "roomfix.detector_view_t") return Kind::kDetectorView;
  if (type_name == "roomfix.detector_view_request_t") return Kind::kDetectorViewRequest;
  return Kind::kNone;
}

// The counter columns of one STATUS file: rejected reasons and counters,
// each sorted, with their column index among them.
struct CounterColumns {
  std::map<std::string, size_t> rejected;
  std::map<std::string, size_t> counters;
  std::vector<std::string> Names() const {
    std::vector<std::string> out(rejected.size() + counters.size());
    for (const auto& [name, i] : rejected) out[i] = kRejectedPrefix + name;
    for (const auto& [name, i] : counters) out[i] = kCountersPrefix + name;
    return out;
  }
};

std::string PoseRow(const pose2d_t& m, int64_t recv_utime, int64_t start) {
  CsvLine line;
  PutTimes(&line, recv_utime, m.utime, start);
  line.Int(m.robot_id);
  line.Int(m.camera_id);
  line.Real(m.x_m);
  line.Real(m.y_m);
  line.Real(m.z_m);
  line.Real(m.heading_rad);
  for (const auto& row : m.covariance) {
    for (double v : row) line.Real(v);
  }
  line.Int(m.status);
  line.Text(kPoseStatusNames[m.status]);
  line.Int(m.source);
  line.Text(kSourceNames[m.source]);
  line.Int(m.latency_us);
  line.Int(m.measurement_seq);
  line.Real(m.residual_m);
  line.Int(m.num_measurements);
  return line.Take();
}

// One row per range; a set without ranges is one row with the range
// columns empty, so every firing has a row.
std::string RangeRows(const range_set_t& m, int64_t recv_utime, int64_t start, int64_t* rows) {
  std::string out;
  const size_t n = std::max<size_t>(m.ranges.size(), 1);
  for (size_t i = 0; i < n; ++i) {
    CsvLine line;
    PutTimes(&line, recv_utime, m.utime, start);
    line.Int(m.beacon_id);
    line.Int(m.firing_seq);
    line.Real(m.speed_of_sound_mps);
    line.Real(m.temperature_c);
    line.Int(m.num_expected);
    line.Int(static_cast<int64_t>(m.ranges.size()));
    if (i < m.ranges.size()) {
      const range_t& r = m.ranges[i];
      line.Int(static_cast<int64_t>(i));
      line.Int(r.receiver_id);
      for (double v : r.receiver_position_m) line.Real(v);
      line.Real(r.time_of_flight_us);
      line.Real(r.range_m);
      line.Int(r.arrival_utime);
      line.Seconds(r.arrival_utime, start);
    } else {
      for (int k = 0; k < 9; ++k) line.Empty();
    }
    out += line.Take();
  }
  *rows += static_cast<int64_t>(n);
  return out;
}

// One row per marker; a frame without markers is one row with the marker
// columns empty, so every frame has a row.
std::string MarkerRows(const marker_pixels_t& m, int64_t recv_utime, int64_t start, int64_t* rows) {
  std::string out;
  const size_t n = std::max<size_t>(m.markers.size(), 1);
  for (size_t i = 0; i < n; ++i) {
    CsvLine line;
    PutTimes(&line, recv_utime, m.utime, start);
    line.Int(m.camera_id);
    line.Int(m.frame_seq);
    line.Int(m.width_px);
    line.Int(m.height_px);
    line.Int(m.search_mode);
    line.Text(kSearchModeNames[m.search_mode]);
    line.Int(m.processing_time_us);
    line.Int(static_cast<int64_t>(m.markers.size()));
    if (i < m.markers.size()) {
      const marker_t& k = m.markers[i];
      line.Int(static_cast<int64_t>(i));
      line.Text(k.colour_class);
      line.Int(k.robot_id);
      line.Int(k.role);
      line.Text(kRoleNames[k.role]);
      line.Real(k.u_px);
      line.Real(k.v_px);
      line.Real(k.radius_px);
      line.Real(k.circularity);
      line.Real(k.area_px);
    } else {
      for (int k = 0; k < 10; ++k) line.Empty();
    }
    out += line.Take();
  }
  *rows += static_cast<int64_t>(n);
  return out;
}

std::string StatusRow(const process_status_t& m, int64_t recv_utime, int64_t start,
                      const CounterColumns& columns) {
  CsvLine line;
  PutTimes(&line, recv_utime, m.utime, start);
  line.Text(m.process);
  line.Text(m.host);
  line.Int(m.pid);
  line.Int(m.uptime_us);
  line.Int(m.state);
  line.Text(kStateNames[m.state]);
  line.Int(m.inputs);
  line.Int(m.outputs);
  line.Int(m.dropped);
  line.Text(m.last_error);
  line.Int(m.last_error_utime);
  // A name listed twice in one heartbeat (malformed) keeps the last count,
  // as `roomfix listen`'s JSON object does; a name the heartbeat lacks is
  // an empty field.
  std::vector<const int64_t*> cells(columns.rejected.size() + columns.counters.size(), nullptr);
  for (const counter_t& c : m.rejected) {
    auto it = columns.rejected.find(c.name);
    if (it != columns.rejected.end()) cells[it->second] = &c.count;
  }
  for (const counter_t& c : m.counters) {
    auto it = columns.counters.find(c.name);
    if (it != columns.counters.end()) cells[it->second] = &c.count;
  }
  for (const int64_t* v : cells) {
    if (v != nullptr) {
      line.Int(*v);
    } else {
      line.Empty();
    }
  }
  return line.Take();
}

std::string ImageRow(const image_t& m, int64_t recv_utime, int64_t start) {
  CsvLine line;
  PutTimes(&line, recv_utime, m.utime, start);
  line.Int(m.camera_id);
  line.Int(m.frame_seq);
  line.Int(m.width_px);
  line.Int(m.height_px);
  line.Int(m.source_width_px);
  line.Int(m.source_height_px);
  line.Text(m.format);
  line.Int(m.num_bytes);
  return line.Take();
}

// One row per view: the image summarised, the robots as "id:reason" pairs
// (the reason's wire code, docs/messages.md) joined by ";".
std::string DetectorViewRow(const detector_view_t& m, int64_t recv_utime, int64_t start) {
  CsvLine line;
  PutTimes(&line, recv_utime, m.utime, start);
  for (const int64_t v :
       {int64_t{m.camera_id}, m.frame_seq, int64_t{m.width_px}, int64_t{m.height_px},
        int64_t{m.source_width_px}, int64_t{m.source_height_px}, int64_t{m.region_u_px},
        int64_t{m.region_v_px}, int64_t{m.region_width_px}, int64_t{m.region_height_px},
        int64_t{m.scale}}) {
    line.Int(v);
  }
  line.Text(m.format);
  line.Int(m.num_bytes);
  line.Int(m.num_robots);
  std::string reasons;
  for (const detector_view_robot_t& r : m.robots) {
    reasons += (reasons.empty() ? "" : ";") + std::to_string(r.robot_id) + ":" +
               std::to_string(static_cast<int>(r.reason));
  }
  line.Text(reasons);
  return line.Take();
}

std::string DetectorViewRequestRow(const detector_view_request_t& m, int64_t recv_utime,
                                   int64_t start) {
  CsvLine line;
  PutTimes(&line, recv_utime, m.utime, start);
  line.Int(m.camera_id);
  line.Int(m.region_u_px);
  line.Int(m.region_v_px);
  line.Int(m.region_width_px);
  line.Int(m.region_height_px);
  line.Real(m.rate_hz);
  line.Real(m.duration_s);
  return line.Take();
}

std::string SiteRow(const site_t& m, int64_t recv_utime, int64_t start) {
  CsvLine line;
  PutTimes(&line, recv_utime, m.utime, start);
  line.Text(m.site_name);
  line.Text(m.site_path);
  line.Int(static_cast<int64_t>(m.site_text.size()));
  line.Int(static_cast<int64_t>(m.files.size()));
  std::string names;
  for (const site_file_t& f : m.files) names += (names.empty() ? "" : ";") + f.name;
  line.Text(names);
  line.Text(m.missing);
  line.Text(m.content_hash);
  line.Text(m.roomfix_version);
  line.Text(m.process);
  line.Text(m.host);
  line.Int(m.pid);
  return line.Take();
}

// A CSV file being written; every write is checked and the first failure
// kept (a full disk is reported, not a short file passed off as whole).
class CsvFile {
 public:
  static std::unique_ptr<CsvFile> Create(const std::string& path, std::string* error) {
    FILE* f = std::fopen(path.c_str(), "w");
    if (f == nullptr) {
      *error = path + ": cannot write: " + std::strerror(errno);
      return nullptr;
    }
    return std::unique_ptr<CsvFile>(new CsvFile(f, path));
  }
  ~CsvFile() {
    if (file_ != nullptr) std::fclose(file_);
  }
  void Write(const std::string& text) {
    if (!error_.empty()) return;
    if (std::fwrite(text.data(), 1, text.size(), file_) != text.size()) {
      error_ = path_ + ": cannot write: " + std::strerror(errno);
    }
  }
  // False with the first failure (a write, the flush or the close).
  bool Close(std::string* error) {
    const bool flushed = std::fflush(file_) == 0 && std::ferror(file_) == 0;
    if (error_.empty() && !flushed) error_ = path_ + ": cannot write: " + std::strerror(errno);
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (error_.empty() && !closed) error_ = path_ + ": cannot write: " + std::strerror(errno);
    *error = error_;
    return error_.empty();
  }

 private:
  CsvFile(FILE* file, std::string path) : file_(file), path_(std::move(path)) {}
  FILE* file_;
  std::string path_;
  std::string error_;
};

// The file name for a channel's (and type's) CSV (CsvFileReport::file).
std::string FileBase(const std::string& channel) {
  std::string base;
  for (char c : channel.substr(0, 100)) {
    const bool keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '_' || c == '-' || c == '.';
    base += keep ? c : '_';
  }
  // "", "." and ".." name no file of their own; a leading dot would hide it.
  if (base.empty() || base[0] == '.') base.insert(base.begin(), '_');
  return base;
}

// Adds one to a by-name count, folding names past the cap into "<other>".
void CountByName(std::map<std::string, int64_t>* counts, const std::string& name) {
  auto it = counts->find(name);
  if (it == counts->end() && counts->size() >= kMaxCsvListedChannels) {
    it = counts->emplace(kOtherChannels, 0).first;
  } else if (it == counts->end()) {
    it = counts->emplace(name, 0).first;
  }
  ++it->second;
}

// Distinct counter names past the column cap are counted up to this many
// (a hostile log could invent millions; the count then says "at least").
constexpr size_t kMaxOverCapNamesCounted = 1 << 16;

// The STATUS counter names on each channel (first pass over the log: the
// header of a STATUS file names every counter its rows will have).
std::map<std::string, CounterColumns> CollectCounterColumns(const std::string& path,
                                                            int64_t* names_not_exported) {
  std::map<std::string, std::pair<std::set<std::string>, std::set<std::string>>> names;
  std::set<std::pair<std::string, std::string>> over_cap;
  std::string error;
  auto reader = LogReader::Open(path, &error);
  LogEvent event;
  while (reader != nullptr && reader->Next(&event)) {
    const int size = static_cast<int>(event.data.size());
    const char* type = RoomfixTypeName(event.data.data(), size);
    process_status_t m;
    if (type == nullptr || std::strcmp(type, "roomfix.process_status_t") != 0 ||
        (names.size() >= kMaxCsvFiles && names.count(event.channel) == 0) ||
        !DecodeChecked(event.data.data(), size, &m, nullptr)) {
      continue;
    }
    auto& [rejected, counters] = names[event.channel];
    auto add = [&](std::set<std::string>* into, const std::string& name, const char* prefix) {
      if (into->count(name) > 0) return;
      if (rejected.size() + counters.size() < kMaxCsvCounterColumns) {
        into->insert(name);
      } else if (over_cap.size() < kMaxOverCapNamesCounted) {
        over_cap.insert({event.channel, prefix + name});
      }
    };
    for (const counter_t& c : m.rejected) add(&rejected, c.name, kRejectedPrefix);
    for (const counter_t& c : m.counters) add(&counters, c.name, kCountersPrefix);
  }
  *names_not_exported = static_cast<int64_t>(over_cap.size());
  std::map<std::string, CounterColumns> out;
  for (const auto& [channel, sets] : names) {
    CounterColumns& c = out[channel];
    size_t i = 0;
    for (const std::string& n : sets.first) c.rejected[n] = i++;
    for (const std::string& n : sets.second) c.counters[n] = i++;
  }
  return out;
}

// Everything the second pass keeps per output file.
struct OpenFile {
  CsvFileReport report;
  Kind kind = Kind::kNone;
  std::unique_ptr<CsvFile> file;
  const CounterColumns* counters = nullptr;
};

class Exporter {
 public:
  Exporter(const CsvExportOptions& options, CsvExportReport* report)
      : options_(options), report_(report) {
    // Names are kept without ".csv": the index's and the damage list's
    // must be taken, or a channel called "_channels" would overwrite one.
    for (const std::string file : {kCsvChannelsFile, kCsvDamageFile}) {
      used_names_.insert(file.substr(0, file.size() - 4));
    }
  }

  bool Run() {
    counter_columns_ =
        CollectCounterColumns(options_.log_path, &report_->counter_names_not_exported);
    auto reader = LogReader::Open(options_.log_path, &report_->error);
    if (reader == nullptr) return false;
    LogEvent event;
    int64_t regions_seen = 0;
    int64_t last_utime = -1;
    while (reader->Next(&event)) {
      if (report_->events++ == 0) report_->start_utime = event.utime;
      // Damage found before this event lies between it and the last one.
      for (; regions_seen < reader->damage_regions(); ++regions_seen) {
        AddDamageRegion(*reader, regions_seen, last_utime, event.utime);
      }
      last_utime = event.utime;
      Export(event);
      if (!error_.empty()) break;
    }
    for (; regions_seen < reader->damage_regions(); ++regions_seen) {
      AddDamageRegion(*reader, regions_seen, last_utime, -1);
    }
    report_->damaged = reader->damaged();
    report_->bytes_skipped = reader->bytes_skipped();
    report_->damage = reader->DamageSummary();
    return Finish();
  }

 private:
  void AddDamageRegion(const LogReader& reader, int64_t index, int64_t before, int64_t after) {
    if (index >= static_cast<int64_t>(reader.damage().size())) return;  // past the kept ones
    report_->damage_regions.push_back({reader.damage()[static_cast<size_t>(index)], before, after});
  }

  void Export(const LogEvent& event) {
    const int size = static_cast<int>(event.data.size());
    const char* type = RoomfixTypeName(event.data.data(), size);
    if (type == nullptr) {
      CountByName(&report_->foreign, event.channel);
      return;
    }
    OpenFile* out = FileFor(event.channel, type);
    if (out == nullptr) {
      ++report_->events_not_exported;
      return;
    }
    ++out->report.events;
    std::string reason;
    std::string rows;
    if (!Rows(out, event, &rows, &reason)) {
      ++out->report.refused;
      CountByName(&report_->refused, event.channel + "." + reason);
      return;
    }
    out->file->Write(rows);
  }

  // The rows of one event, or false with the refusal reason.
  bool Rows(OpenFile* out, const LogEvent& event, std::string* rows, std::string* reason) {
    const void* data = event.data.data();
    const int size = static_cast<int>(event.data.size());
    const int64_t start = report_->start_utime;
    switch (out->kind) {
      case Kind::kPose: {
        pose2d_t m;
        if (!DecodeChecked(data, size, &m, reason)) return false;
        *rows = PoseRow(m, event.utime, start);
        ++out->report.rows;
        return true;
      }
      case Kind::kRanges: {
        range_set_t m;
        if (!DecodeChecked(data, size, &m, reason)) return false;
        *rows = RangeRows(m, event.utime, start, &out->report.rows);
        return true;
      }
      case Kind::kMarkers: {
        marker_pixels_t m;
        if (!DecodeChecked(data, size, &m, reason)) return false;
        *rows = MarkerRows(m, event.utime, start, &out->report.rows);
        return true;
      }
      case Kind::kStatus: {
        process_status_t m;
        if (!DecodeChecked(data, size, &m, reason)) return false;
        *rows = StatusRow(m, event.utime, start, *out->counters);
        ++out->report.rows;
        return true;
      }
      case Kind::kImage: {
        image_t m;
        if (!DecodeChecked(data, size, &m, reason)) return false;
        *rows = ImageRow(m, event.utime, start);
        ++out->report.rows;
        return true;
      }
      case Kind::kSite: {
        site_t m;
        if (!DecodeChecked(data, size, &m, reason)) return false;
        *rows = SiteRow(m, event.utime, start);
        ++out->report.rows;
        return true;
      }
      case Kind::kDetectorView: {
        detector_view_t m;
        if (!DecodeChecked(data, size, &m, reason)) return false;
        *rows = DetectorViewRow(m, event.utime, start);
        ++out->report.rows;
        return true;
      }
      case Kind::kDetectorViewRequest: {
        detector_view_request_t m;
        if (!DecodeChecked(data, size, &m, reason)) return false;
        *rows = DetectorViewRequestRow(m, event.utime, start);
        ++out->report.rows;
        return true;
      }
      case Kind::kNone:
        break;
    }
    *reason = kUnknownTypeReason;
    return false;
  }

  // The file of a (channel, type), made with its header at first use;
  // nullptr past kMaxCsvFiles or when it cannot be made (error_ then set).
  OpenFile* FileFor(const std::string& channel, const std::string& type) {
    const auto key = std::make_pair(channel, type);
    auto it = files_.find(key);
    if (it != files_.end()) return &it->second;
    if (files_.size() >= kMaxCsvFiles) return nullptr;
    std::string base = FileBase(channel);
    if (types_on_channel_[channel]++ > 0) base += "." + type.substr(type.find('.') + 1);
    std::string name = base;
    for (int n = 2; used_names_.count(name) > 0; ++n) name = base + "_" + std::to_string(n);
    used_names_.insert(name);
    OpenFile out;
    out.report = {name + ".csv", channel, type};
    out.kind = KindOf(type);
    out.file = CsvFile::Create(options_.out_dir + "/" + out.report.file, &error_);
    if (out.file == nullptr) return nullptr;
    std::vector<std::string> columns = CsvColumns(type);
    if (out.kind == Kind::kStatus) {
      out.counters = &counter_columns_[channel];
      for (std::string& c : out.counters->Names()) columns.push_back(std::move(c));
    }
    out.file->Write(HeaderLine(columns));
    order_.push_back(key);
    return &files_.emplace(key, std::move(out)).first->second;
  }

  // Closes every file and writes the index and the damage list.
  bool Finish() {
    for (const auto& key : order_) {
      OpenFile& f = files_.at(key);
      std::string error;
      if (!f.file->Close(&error) && error_.empty()) error_ = error;
      report_->files.push_back(f.report);
    }
    WriteIndex();
    WriteDamage();
    report_->error = error_;
    return error_.empty();
  }

  void WriteIndex() {
    std::string error;
    auto index = CsvFile::Create(options_.out_dir + "/" + kCsvChannelsFile, &error);
    if (index == nullptr) {
      if (error_.empty()) error_ = error;
      return;
    }
    index->Write(HeaderLine({"file", "channel", "type", "events", "rows", "refused"}));
    for (const CsvFileReport& f : report_->files) {
      CsvLine line;
      line.Text(f.file);
      line.Text(f.channel);
      line.Text(f.type);
      line.Int(f.events);
      line.Int(f.rows);
      line.Int(f.refused);
      index->Write(line.Take());
    }
    if (!index->Close(&error) && error_.empty()) error_ = error;
  }

  void WriteDamage() {
    std::string error;
    auto out = CsvFile::Create(options_.out_dir + "/" + kCsvDamageFile, &error);
    if (out == nullptr) {
      if (error_.empty()) error_ = error;
      return;
    }
    out->Write(HeaderLine({"offset", "bytes", "reason", "recv_utime_before", "recv_s_before",
                           "recv_utime_after", "recv_s_after"}));
    for (const CsvDamageRegion& d : report_->damage_regions) {
      CsvLine line;
      line.Int(d.damage.offset);
      line.Int(d.damage.bytes);
      line.Text(d.damage.reason);
      for (int64_t t : {d.utime_before, d.utime_after}) {
        if (t < 0) {
          line.Empty();
          line.Empty();
        } else {
          line.Int(t);
          line.Seconds(t, report_->start_utime);
        }
      }
      out->Write(line.Take());
    }
    if (!out->Close(&error) && error_.empty()) error_ = error;
  }

  const CsvExportOptions& options_;
  CsvExportReport* report_;
  std::map<std::string, CounterColumns> counter_columns_;
  std::map<std::pair<std::string, std::string>, OpenFile> files_;
  std::vector<std::pair<std::string, std::string>> order_;
  std::map<std::string, int> types_on_channel_;
  std::set<std::string> used_names_;
  std::string error_;
};

// Makes the output folder, or refuses it (a file, a non-empty folder
// without --force).
bool PrepareFolder(const CsvExportOptions& o, std::string* error) {
  std::error_code ec;
  const fs::file_status st = fs::status(o.out_dir, ec);
  if (fs::exists(st) && !fs::is_directory(st)) {
    *error = o.out_dir + ": not a folder";
    return false;
  }
  if (!fs::exists(st)) {
    if (!fs::create_directories(o.out_dir, ec)) {
      *error = o.out_dir + ": cannot make the folder: " + ec.message();
      return false;
    }
    return true;
  }
  if (!o.force && !fs::is_empty(o.out_dir, ec)) {
    *error = o.out_dir +
             ": not empty (--force writes into it, replacing files of the same names; other "
             "files stay)";
    return false;
  }
  if (ec) {
    *error = o.out_dir + ": " + ec.message();
    return false;
  }
  return true;
}

}  // namespace

bool CsvExportOptions::IsValid(std::string* error) const {
  if (log_path.empty()) {
    *error = "no log given";
    return false;
  }
  if (out_dir.empty()) {
    *error = "no output folder given (--csv DIR)";
    return false;
  }
  return true;
}

std::string CsvField(const std::string& text) {
  std::string v = text;
  if (std::any_of(v.begin(), v.end(),
                  [](char c) { return static_cast<unsigned char>(c) >= 0x80; })) {
    // nlohmann's replacing dump turns every invalid sequence into U+FFFD;
    // parsing it back gives the repaired text.
    const std::string quoted =
        nlohmann::json(v).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    v = nlohmann::json::parse(quoted).get<std::string>();
  }
  const bool quote = v.find_first_of(",\"\r\n") != std::string::npos ||
                     (!v.empty() && (v.front() == ' ' || v.back() == ' '));
  if (!quote) return v;
  std::string out = "\"";
  for (char c : v) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::vector<std::string> CsvColumns(const std::string& type_name) {
  switch (KindOf(type_name)) {
    case Kind::kPose:
      return WithTimes({"robot_id",
                        "camera_id",
                        "x_m",
                        "y_m",
                        "z_m",
                        "heading_rad",
                        "cov_xx_m2",
                        "cov_xy_m2",
                        "cov_xh_m_rad",
                        "cov_yx_m2",
                        "cov_yy_m2",
                        "cov_yh_m_rad",
                        "cov_hx_m_rad",
                        "cov_hy_m_rad",
                        "cov_hh_rad2",
                        "status",
                        "status_name",
                        "source",
                        "source_name",
                        "latency_us",
                        "measurement_seq",
                        "residual_m",
                        "num_measurements"});
    case Kind::kRanges:
      return WithTimes({"beacon_id", "firing_seq", "speed_of_sound_mps", "temperature_c",
                        "num_expected", "num_ranges", "range_index", "receiver_id", "receiver_x_m",
                        "receiver_y_m", "receiver_z_m", "time_of_flight_us", "range_m",
                        "arrival_utime", "arrival_s"});
    case Kind::kMarkers:
      return WithTimes({"camera_id", "frame_seq", "width_px", "height_px", "search_mode",
                        "search_mode_name", "processing_time_us", "num_markers", "marker_index",
                        "colour_class", "robot_id", "role", "role_name", "u_px", "v_px",
                        "radius_px", "circularity", "area_px"});
    case Kind::kStatus:
      return WithTimes({"process", "host", "pid", "uptime_us", "state", "state_name", "inputs",
                        "outputs", "dropped", "last_error", "last_error_utime"});
    case Kind::kImage:
      return WithTimes({"camera_id", "frame_seq", "width_px", "height_px", "source_width_px",
                        "source_height_px", "format", "num_bytes"});
    case Kind::kSite:
      return WithTimes({"site_name", "site_path", "site_text_bytes", "num_files", "file_names",
                        "missing", "content_hash", "roomfix_version", "process", "host", "pid"});
    case Kind::kDetectorView:
      return WithTimes({"camera_id", "frame_seq", "width_px", "height_px", "source_width_px",
                        "source_height_px", "region_u_px", "region_v_px", "region_width_px",
                        "region_height_px", "scale", "format", "num_bytes", "num_robots",
                        "robot_reasons"});
    case Kind::kDetectorViewRequest:
      return WithTimes({"camera_id", "region_u_px", "region_v_px", "region_width_px",
                        "region_height_px", "rate_hz", "duration_s"});
    case Kind::kNone:
      break;
  }
  return {};
}

CsvExportReport ExportLogToCsv(const CsvExportOptions& options) {
  CsvExportReport report;
  if (!options.IsValid(&report.error)) return report;
  {
    // Opened first so that a missing log leaves no folder behind.
    auto reader = LogReader::Open(options.log_path, &report.error);
    if (reader == nullptr) return report;
  }
  if (!PrepareFolder(options, &report.error)) return report;
  Exporter exporter(options, &report);
  exporter.Run();
  return report;
}

}  // namespace roomfix
