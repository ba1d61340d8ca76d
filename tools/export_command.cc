// roomfix export LOG --csv DIR: every roomfix message of a log as CSV, one
// file per channel (tools/csv_export.h; docs/export.md lists the columns).
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <string>

#include "tools/commands.h"
#include "tools/csv_export.h"

namespace roomfix {
namespace {

// "PMD_INFO2 40, PMD_ORDERS2 12" for a by-channel count.
std::string ChannelCounts(const std::map<std::string, int64_t>& counts, int64_t* total) {
  std::string out;
  *total = 0;
  for (const auto& [name, count] : counts) {
    out += (out.empty() ? "" : ", ") + name + " " + std::to_string(count);
    *total += count;
  }
  return out;
}

// Says what was written (stdout) and what was not (stderr); the exit code.
int Report(const CsvExportOptions& o, const CsvExportReport& r) {
  fmt::print("{}: {} events, {} files in {} (and {}, {})\n", o.log_path, r.events, r.files.size(),
             o.out_dir, kCsvChannelsFile, kCsvDamageFile);
  fmt::print("{:<28} {:<24} {:<26} {:>8} {:>8} {:>8}\n", "file", "channel", "type", "events",
             "rows", "refused");
  // Channel names come from the log: printed as C strings, up to a NUL byte.
  for (const CsvFileReport& f : r.files) {
    fmt::print("{:<28} {:<24} {:<26} {:8} {:8} {:8}\n", f.file.c_str(), f.channel.c_str(),
               f.type.c_str(), f.events, f.rows, f.refused);
  }
  std::fflush(stdout);
  int64_t total = 0;
  if (!r.refused.empty()) {
    const std::string by_channel = ChannelCounts(r.refused, &total);
    std::cerr << "roomfix export: warning: " << total << " events refused, no row written ("
              << by_channel << ")\n";
  }
  if (!r.foreign.empty()) {
    const std::string by_channel = ChannelCounts(r.foreign, &total);
    std::cerr << "roomfix export: note: " << total << " events of no roomfix type not exported ("
              << by_channel << ")\n";
  }
  if (r.events_not_exported > 0) {
    std::cerr << "roomfix export: warning: more than " << kMaxCsvFiles << " channels; "
              << r.events_not_exported << " events on the rest not exported\n";
  }
  if (r.counter_names_not_exported > 0) {
    std::cerr << "roomfix export: warning: " << r.counter_names_not_exported
              << " STATUS counter names past the first " << kMaxCsvCounterColumns
              << " of a channel have no column\n";
  }
  if (r.damaged) {
    // Every good event before and after the damage is in the files.
    fmt::print("damaged: {}\n", r.damage);
    std::fflush(stdout);
    std::cerr << "roomfix export: warning: " << o.log_path << ": " << r.damage << " (listed in "
              << kCsvDamageFile << ")\n";
    return 2;
  }
  return 0;
}

}  // namespace

void AddExportCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "export",
      "Write every roomfix message of an LCM log as CSV, one file per channel "
      "(docs/export.md); exit 2 when the log is damaged (the good events are exported)");
  auto o = std::make_shared<CsvExportOptions>();
  cmd->add_option("LOG", o->log_path, "LCM log file (roomfix_logger or lcm-logger)")->required();
  cmd->add_option("--csv", o->out_dir,
                  "Folder for the CSV files, made if missing; refused when it holds files "
                  "(see --force)")
      ->required();
  cmd->add_flag("--force", o->force,
                "Write into a folder that holds files, replacing those of the same names");
  cmd->callback([o, exit_code] {
    const CsvExportReport report = ExportLogToCsv(*o);
    if (!report.error.empty()) {
      std::cerr << "roomfix export: " << report.error << "\n";
      *exit_code = 1;
      return;
    }
    *exit_code = Report(*o, report);
  });
}

}  // namespace roomfix
