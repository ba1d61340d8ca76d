#ifndef ROOMFIX_TOOLS_CSV_EXPORT_H_
#define ROOMFIX_TOOLS_CSV_EXPORT_H_

// `roomfix export LOG --csv DIR` (docs/export.md): every roomfix message of
// an LCM log as CSV, one file per channel (and type), flattened for plotting
// in pandas, a spreadsheet or PlotJuggler.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "msgio/log.h"

namespace roomfix {

struct CsvExportOptions {
  std::string log_path;
  std::string out_dir;
  // Write into a folder that already holds files (files of the same names
  // are replaced, others left alone). Off: a non-empty folder is refused, so
  // an earlier export's CSVs of other channels cannot pass for this log's.
  bool force = false;

  bool IsValid(std::string* error) const;
};

// One CSV file written.
struct CsvFileReport {
  // Name inside the output folder: the channel with every byte outside
  // [A-Za-z0-9_.-] replaced by '_' (a channel is a publisher's choice),
  // ".csv"; a second type on one channel adds ".<type>", a clash "_2".
  std::string file;
  std::string channel;
  // "roomfix.pose2d_t".
  std::string type;
  int64_t events = 0;
  int64_t rows = 0;
  // Events refused before decoding (DecodeChecked); no row for them.
  int64_t refused = 0;
};

// A stretch of the log that held no readable event, with the receive times
// of the good events either side (-1: none), so a plot's gap can be told
// from a pause in the recording.
struct CsvDamageRegion {
  LogDamage damage;
  int64_t utime_before = -1;
  int64_t utime_after = -1;
};

struct CsvExportReport {
  // Set when nothing was exported (the log cannot be opened, the folder
  // cannot be made or written); the rest is then meaningless.
  std::string error;
  int64_t events = 0;
  // The first good event's receive time: every `*_s` column counts seconds
  // from it.
  int64_t start_utime = 0;
  std::vector<CsvFileReport> files;
  // Events that are no roomfix type (bot-procman's PMD_*, LCM's self test),
  // by channel; past kMaxCsvListedChannels names the rest count under
  // "<other>".
  std::map<std::string, int64_t> foreign;
  // Events refused by DecodeChecked, "<CHANNEL>.<reason>" as a process's
  // STATUS names them (same fold into "<other>").
  std::map<std::string, int64_t> refused;
  // Events on channels past the first kMaxCsvFiles (channel, type) pairs.
  int64_t events_not_exported = 0;
  // Distinct STATUS counter names past kMaxCsvCounterColumns in one file
  // (counted up to 65536).
  int64_t counter_names_not_exported = 0;
  // Bytes skipped (LogReader): every good event around them is exported.
  bool damaged = false;
  int64_t bytes_skipped = 0;
  std::string damage;  // LogReader::DamageSummary()
  std::vector<CsvDamageRegion> damage_regions;
};

// A log is outside input: anyone can invent channels, counter names and
// damage, so what the export keeps is bounded.
inline constexpr size_t kMaxCsvFiles = 64;
inline constexpr size_t kMaxCsvCounterColumns = 1024;
inline constexpr size_t kMaxCsvListedChannels = 1024;
// The index of the files written and the damage found, always written
// (header only when there is nothing to list); no channel's file takes
// these names.
inline constexpr char kCsvChannelsFile[] = "_channels.csv";
inline constexpr char kCsvDamageFile[] = "_damage.csv";

// Reads the log with LogReader (past damage), decodes every event only
// through DecodeChecked and writes the CSVs. Never throws.
CsvExportReport ExportLogToCsv(const CsvExportOptions& options);

// The columns of a type's CSV in order ("roomfix.pose2d_t"; empty for an
// unknown type). process_status_t's file continues with one column per
// rejected reason ("rejected/<name>") and per counter ("counters/<name>")
// found in the log's heartbeats on that channel, each group sorted.
std::vector<std::string> CsvColumns(const std::string& type_name);

// One CSV field as written: quoted (quotes doubled) when it holds a comma,
// a quote, a CR or an LF, or starts or ends with a space; bytes that are not
// UTF-8 become U+FFFD, so pandas' default UTF-8 reading never fails.
std::string CsvField(const std::string& text);

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_CSV_EXPORT_H_
