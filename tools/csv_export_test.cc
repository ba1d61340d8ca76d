// roomfix export's CSV files (csv_export.h): the columns of every type, one
// row per range and per marker, STATUS counters as columns, strings a
// spreadsheet reads back, refused and foreign events, hostile channel names,
// and a log damaged in the middle and at its end.
#include "tools/csv_export.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "msgio/log.h"
#include "tests/testing/raw_log_event.h"
#include "tests/testing/test_messages.h"
#include "tests/testing/test_paths.h"
#include "tests/testing/wire_test_messages.h"

namespace roomfix {
namespace {

using testing::MakeTestPose;
using testing::ReadFile;
using testing::TempDir;

constexpr int64_t kT0 = 1'700'000'000'000'000;
// The logger's receive time lags the message's own time by this much here.
constexpr int64_t kRecvLag_us = 2'500;

using Table = std::vector<std::vector<std::string>>;

// RFC 4180 as the writer produces it: fields split at commas outside
// quotes, "" inside quotes is one quote, lines end at LF outside quotes.
Table ParseCsv(const std::string& text) {
  Table rows(1, std::vector<std::string>(1));
  bool quoted = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        rows.back().back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        rows.back().back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      rows.back().emplace_back();
    } else if (c == '\n') {
      rows.emplace_back(1);
    } else {
      rows.back().back() += c;
    }
  }
  if (rows.back() == std::vector<std::string>(1)) rows.pop_back();
  return rows;
}

// A CSV file as header -> column, rows of name -> value.
struct Csv {
  std::vector<std::string> header;
  std::vector<std::map<std::string, std::string>> rows;
};

Csv ReadCsv(const std::string& path) {
  const Table t = ParseCsv(ReadFile(path));
  Csv out;
  if (t.empty()) return out;
  out.header = t[0];
  for (size_t r = 1; r < t.size(); ++r) {
    EXPECT_EQ(t[r].size(), out.header.size()) << path << " row " << r;
    std::map<std::string, std::string> row;
    for (size_t c = 0; c < t[r].size() && c < out.header.size(); ++c) row[out.header[c]] = t[r][c];
    out.rows.push_back(row);
  }
  return out;
}

double Number(const std::string& text) { return std::strtod(text.c_str(), nullptr); }

template <class Msg>
void Put(LogWriter* writer, int64_t recv_utime, const std::string& channel, const Msg& msg) {
  const std::vector<uint8_t> bytes = testing::Encode(msg);
  std::string error;
  ASSERT_TRUE(
      writer->Write(recv_utime, channel, bytes.data(), static_cast<int>(bytes.size()), &error))
      << error;
}

class CsvExportTest : public ::testing::Test {
 protected:
  TempDir dir_;
  std::string log_ = dir_.File("run.lcm");
  std::string out_ = dir_.File("csv");

  std::unique_ptr<LogWriter> NewLog() {
    std::string error;
    auto writer = LogWriter::Create(log_, false, &error);
    EXPECT_NE(writer, nullptr) << error;
    return writer;
  }
  CsvExportReport Export() {
    CsvExportOptions o;
    o.log_path = log_;
    o.out_dir = out_;
    return ExportLogToCsv(o);
  }
  Csv File(const std::string& name) { return ReadCsv(out_ + "/" + name); }
};

// The column tables of docs/export.md: every column of every type's file is
// named in the first cell of a table row there (`x_m`, or `x_m`, `y_m`), so
// the documentation cannot fall behind the files.
TEST_F(CsvExportTest, EveryColumnOfEveryTypeIsDocumented) {
  std::istringstream doc(ReadFile(testing::SourceDir() + "/docs/export.md"));
  std::set<std::string> documented;
  // Each `name` of the cell (not std::regex: tests/build/no_std_regex.sh).
  for (std::string line; std::getline(doc, line);) {
    if (line.rfind("| `", 0) != 0) continue;
    const std::string cell = line.substr(1, line.find('|', 1) - 1);
    for (size_t open = cell.find('`'); open != std::string::npos;) {
      const size_t close = cell.find('`', open + 1);
      if (close == std::string::npos) break;
      if (close > open + 1) documented.insert(cell.substr(open + 1, close - open - 1));
      open = cell.find('`', close + 1);
    }
  }
  ASSERT_FALSE(documented.empty());
  for (const char* type : {"roomfix.pose2d_t", "roomfix.range_set_t", "roomfix.marker_pixels_t",
                           "roomfix.process_status_t", "roomfix.image_t", "roomfix.site_t",
                           "roomfix.detector_view_t", "roomfix.detector_view_request_t"}) {
    const std::vector<std::string> columns = CsvColumns(type);
    ASSERT_FALSE(columns.empty()) << type;
    for (const std::string& c : columns) {
      EXPECT_EQ(documented.count(c), 1u)
          << type << " column " << c << " is not in a table of docs/export.md";
    }
  }
  EXPECT_TRUE(CsvColumns("roomfix.counter_t").empty());
}

TEST_F(CsvExportTest, APoseRowHoldsEveryFieldUnderItsColumn) {
  pose2d_t p = MakeTestPose(kT0 + 100'000, 3, 0.1, 1.0 / 3.0);
  p.source = pose2d_t::SOURCE_CAMERA;
  p.camera_id = 2;
  p.heading_rad = -2.5;
  for (int k = 0; k < 9; ++k) p.covariance[k / 3][k % 3] = 1e-5 * (k + 1) + 1e-21;
  p.status = pose2d_t::STATUS_DEGRADED;
  pose2d_t lost = MakeTestPose(kT0 + 200'000, 3, NAN, NAN);
  lost.status = pose2d_t::STATUS_LOST;
  {
    auto log = NewLog();
    Put(log.get(), kT0, "STATUS", testing::MakeTestStatus());  // the log's start
    Put(log.get(), p.utime + kRecvLag_us, "POSE_CAMERA", p);
    Put(log.get(), lost.utime + kRecvLag_us, "POSE_CAMERA", lost);
  }
  const CsvExportReport r = Export();
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.start_utime, kT0);
  const Csv csv = File("POSE_CAMERA.csv");
  EXPECT_EQ(csv.header, CsvColumns("roomfix.pose2d_t"));
  ASSERT_EQ(csv.rows.size(), 2u);
  const auto& row = csv.rows[0];
  EXPECT_EQ(row.at("recv_utime"), std::to_string(p.utime + kRecvLag_us));
  EXPECT_EQ(row.at("utime"), std::to_string(p.utime));
  // Printed as the decimal itself, not 0.10249999999999999.
  EXPECT_EQ(row.at("utime_s"), "0.1");
  EXPECT_EQ(row.at("recv_s"), "0.1025");
  EXPECT_EQ(row.at("robot_id"), "3");
  EXPECT_EQ(row.at("camera_id"), "2");
  // Doubles are written to read back to the same bits.
  EXPECT_EQ(Number(row.at("x_m")), p.x_m);
  EXPECT_EQ(Number(row.at("y_m")), p.y_m);
  EXPECT_EQ(Number(row.at("z_m")), p.z_m);
  EXPECT_EQ(Number(row.at("heading_rad")), p.heading_rad);
  const char* cov[9] = {"cov_xx_m2",    "cov_xy_m2",    "cov_xh_m_rad", "cov_yx_m2",  "cov_yy_m2",
                        "cov_yh_m_rad", "cov_hx_m_rad", "cov_hy_m_rad", "cov_hh_rad2"};
  for (int k = 0; k < 9; ++k) EXPECT_EQ(Number(row.at(cov[k])), p.covariance[k / 3][k % 3]) << k;
  EXPECT_EQ(row.at("status"), "1");
  EXPECT_EQ(row.at("status_name"), "degraded");
  EXPECT_EQ(row.at("source"), "1");
  EXPECT_EQ(row.at("source_name"), "camera");
  EXPECT_EQ(row.at("latency_us"), "1500");
  EXPECT_EQ(row.at("measurement_seq"), std::to_string(p.measurement_seq));
  EXPECT_EQ(Number(row.at("residual_m")), p.residual_m);
  EXPECT_EQ(row.at("num_measurements"), "4");
  // A lost pose keeps its row; its NaN position is an empty field.
  EXPECT_EQ(csv.rows[1].at("status_name"), "lost");
  EXPECT_EQ(csv.rows[1].at("x_m"), "");
  EXPECT_EQ(csv.rows[1].at("heading_rad"), "");
}

TEST_F(CsvExportTest, ARangeSetIsOneRowPerRangeWithItsFiring) {
  const range_set_t set = testing::MakeTestRangeSet(3);
  const range_set_t empty = testing::MakeTestRangeSet(0);
  {
    auto log = NewLog();
    Put(log.get(), set.utime + kRecvLag_us, "RANGES", set);
    Put(log.get(), set.utime + 2 * kRecvLag_us, "RANGES", empty);
  }
  ASSERT_TRUE(Export().error.empty());
  const Csv csv = File("RANGES.csv");
  EXPECT_EQ(csv.header, CsvColumns("roomfix.range_set_t"));
  ASSERT_EQ(csv.rows.size(), 4u);  // 3 ranges, and the empty set's one row
  for (size_t i = 0; i < 3; ++i) {
    const auto& row = csv.rows[i];
    const range_t& r = set.ranges[i];
    EXPECT_EQ(row.at("firing_seq"), "4242");
    EXPECT_EQ(row.at("beacon_id"), "11");
    EXPECT_EQ(row.at("num_ranges"), "3");
    EXPECT_EQ(row.at("range_index"), std::to_string(i));
    EXPECT_EQ(row.at("receiver_id"), std::to_string(r.receiver_id));
    EXPECT_EQ(Number(row.at("receiver_x_m")), r.receiver_position_m[0]);
    EXPECT_EQ(Number(row.at("receiver_y_m")), r.receiver_position_m[1]);
    EXPECT_EQ(Number(row.at("receiver_z_m")), r.receiver_position_m[2]);
    EXPECT_EQ(Number(row.at("time_of_flight_us")), r.time_of_flight_us);
    EXPECT_EQ(Number(row.at("range_m")), r.range_m);
    EXPECT_EQ(row.at("arrival_utime"), std::to_string(r.arrival_utime));
    EXPECT_EQ(Number(row.at("speed_of_sound_mps")), 343.2);
    EXPECT_EQ(Number(row.at("temperature_c")), 20.5);
  }
  EXPECT_EQ(csv.rows[3].at("num_ranges"), "0");
  EXPECT_EQ(csv.rows[3].at("range_index"), "");
  EXPECT_EQ(csv.rows[3].at("range_m"), "");
}

TEST_F(CsvExportTest, MarkersAreOneRowEachWithTheirFrame) {
  const marker_pixels_t frame = testing::MakeTestMarkerPixels();
  {
    auto log = NewLog();
    Put(log.get(), frame.utime, "MARKER_PIXELS", frame);
  }
  ASSERT_TRUE(Export().error.empty());
  const Csv csv = File("MARKER_PIXELS.csv");
  EXPECT_EQ(csv.header, CsvColumns("roomfix.marker_pixels_t"));
  ASSERT_EQ(csv.rows.size(), 2u);
  EXPECT_EQ(csv.rows[0].at("colour_class"), "orange");
  EXPECT_EQ(csv.rows[1].at("colour_class"), "green");
  EXPECT_EQ(csv.rows[1].at("marker_index"), "1");
  EXPECT_EQ(csv.rows[1].at("frame_seq"), "99");
  EXPECT_EQ(csv.rows[1].at("search_mode_name"), "region_of_interest");
  EXPECT_EQ(csv.rows[1].at("role_name"), "position");
  EXPECT_EQ(Number(csv.rows[1].at("u_px")), 812.25);
  EXPECT_EQ(Number(csv.rows[1].at("area_px")), 615.8);
}

TEST_F(CsvExportTest, StatusHasAColumnPerReasonAndCounterOfTheLog) {
  process_status_t first = testing::MakeTestStatus();
  process_status_t second = testing::MakeTestStatus();
  second.utime += 1'000'000;
  second.counters.push_back(testing::MakeTestCounter("site_hash", 123456789012345));
  second.num_counters = static_cast<int32_t>(second.counters.size());
  second.last_error = "range 3 is \"negative\", again";
  {
    auto log = NewLog();
    Put(log.get(), first.utime, "STATUS", first);
    Put(log.get(), second.utime, "STATUS", second);
  }
  ASSERT_TRUE(Export().error.empty());
  const Csv csv = File("STATUS.csv");
  std::vector<std::string> expected = CsvColumns("roomfix.process_status_t");
  for (const char* c : {"rejected/RANGES.count_over_cap", "rejected/unknown_beacon",
                        "counters/site_hash", "counters/warm_starts"}) {
    expected.push_back(c);
  }
  EXPECT_EQ(csv.header, expected);
  ASSERT_EQ(csv.rows.size(), 2u);
  EXPECT_EQ(csv.rows[0].at("process"), "trilat_proc");
  EXPECT_EQ(csv.rows[0].at("state_name"), "running");
  EXPECT_EQ(csv.rows[0].at("rejected/unknown_beacon"), "7");
  EXPECT_EQ(csv.rows[0].at("counters/warm_starts"), "12");
  EXPECT_EQ(csv.rows[0].at("counters/site_hash"), "");  // not in the first heartbeat
  EXPECT_EQ(csv.rows[1].at("counters/site_hash"), "123456789012345");
  EXPECT_EQ(csv.rows[1].at("last_error"), second.last_error);  // read back through the quotes
}

TEST_F(CsvExportTest, PreviewsAndSitesAreSummarisedOneRowEach) {
  {
    auto log = NewLog();
    Put(log.get(), kT0, "CAMERA_PREVIEW", testing::MakeTestImage());
    Put(log.get(), kT0 + 1, "SITE", testing::MakeTestSite());
  }
  ASSERT_TRUE(Export().error.empty());
  const Csv image = File("CAMERA_PREVIEW.csv");
  EXPECT_EQ(image.header, CsvColumns("roomfix.image_t"));
  ASSERT_EQ(image.rows.size(), 1u);
  EXPECT_EQ(image.rows[0].at("num_bytes"), "13");
  EXPECT_EQ(image.rows[0].at("format"), "jpeg");
  const Csv site = File("SITE.csv");
  EXPECT_EQ(site.header, CsvColumns("roomfix.site_t"));
  ASSERT_EQ(site.rows.size(), 1u);
  EXPECT_EQ(site.rows[0].at("file_names"), "../calibration/demo_room_camera.yaml");
  EXPECT_EQ(site.rows[0].at("content_hash"), std::string(64, 'a'));
  EXPECT_EQ(site.rows[0].at("site_text_bytes"),
            std::to_string(testing::MakeTestSite().site_text.size()));
}

TEST(CsvField, QuotesWhatASpreadsheetWouldSplitAndRepairsBadUtf8) {
  EXPECT_EQ(CsvField("trilat_proc"), "trilat_proc");
  EXPECT_EQ(CsvField("a,b"), "\"a,b\"");
  EXPECT_EQ(CsvField("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(CsvField("two\nlines"), "\"two\nlines\"");
  EXPECT_EQ(CsvField(" padded"), "\" padded\"");
  EXPECT_EQ(CsvField("caf\xc3\xa9"), "caf\xc3\xa9");  // valid UTF-8 kept
  EXPECT_EQ(CsvField("bad\xff"), "bad\xef\xbf\xbd");  // U+FFFD
}

// A status of 7 (enum_out_of_range), a payload of no roomfix type and a
// hostile channel name: counted and reported, never a row or a bad path.
TEST_F(CsvExportTest, RefusedForeignAndHostileEventsAreCountedNotWritten) {
  pose2d_t good = MakeTestPose(kT0, 1, 1.0, 2.0);
  std::vector<uint8_t> bad = testing::Encode(good);
  bad[bad.size() - 9] = 7;  // status: the byte before latency_us
  std::string error;
  {
    auto log = NewLog();
    Put(log.get(), kT0, "POSE_FUSED", good);
    ASSERT_TRUE(
        log->Write(kT0 + 1, "POSE_FUSED", bad.data(), static_cast<int>(bad.size()), &error));
    ASSERT_TRUE(log->Write(kT0 + 2, "PMD_INFO2", "procman!", 8, &error));
    Put(log.get(), kT0 + 3, "../../etc/x", good);
    Put(log.get(), kT0 + 4, "_channels", good);
    Put(log.get(), kT0 + 5, "POSE_FUSED", testing::MakeTestStatus());  // a second type
  }
  const CsvExportReport r = Export();
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(File("POSE_FUSED.csv").rows.size(), 1u);
  EXPECT_EQ(r.refused.at("POSE_FUSED.enum_out_of_range"), 1);
  EXPECT_EQ(r.foreign.at("PMD_INFO2"), 1);
  std::map<std::string, std::string> file_of;
  for (const CsvFileReport& f : r.files) file_of[f.channel + " " + f.type] = f.file;
  EXPECT_EQ(file_of["../../etc/x roomfix.pose2d_t"], "_.._.._etc_x.csv");
  EXPECT_EQ(file_of["_channels roomfix.pose2d_t"], "_channels_2.csv");
  EXPECT_EQ(file_of["POSE_FUSED roomfix.process_status_t"], "POSE_FUSED.process_status_t.csv");
  EXPECT_EQ(File("_.._.._etc_x.csv").rows.size(), 1u);
  // The index names every file with its channel and counts.
  const Csv index = File(kCsvChannelsFile);
  ASSERT_EQ(index.rows.size(), r.files.size());
  EXPECT_EQ(index.rows[0].at("file"), "POSE_FUSED.csv");
  EXPECT_EQ(index.rows[0].at("events"), "2");
  EXPECT_EQ(index.rows[0].at("rows"), "1");
  EXPECT_EQ(index.rows[0].at("refused"), "1");
}

// Garbage in the middle and a cut-off last event: every good event on both
// sides is a row, and _damage.csv places each skipped stretch between the
// receive times of its neighbours.
TEST_F(CsvExportTest, ADamagedLogIsExportedPastItsDamage) {
  constexpr int kPosesPerSide = 5;
  auto pose_event = [](int k) {
    const std::vector<uint8_t> b = testing::Encode(MakeTestPose(kT0 + k * 100'000, 1, 0.01 * k, 2));
    const std::string data(b.begin(), b.end());
    return testing::RawLogEvent(k, kT0 + k * 100'000 + kRecvLag_us, "POSE_ULTRASOUND", data, 15,
                                static_cast<int32_t>(data.size()));
  };
  std::string bytes;
  for (int k = 0; k < kPosesPerSide; ++k) bytes += pose_event(k);
  const int64_t garbage_offset = static_cast<int64_t>(bytes.size());
  std::string garbage(300, '\0');
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<char>(i * 131 + 7);
  bytes += garbage;
  for (int k = kPosesPerSide; k < 2 * kPosesPerSide; ++k) bytes += pose_event(k);
  const std::string last = pose_event(99);
  bytes += last.substr(0, last.size() - 9);
  ASSERT_TRUE(testing::WriteFile(log_, bytes));

  const CsvExportReport r = Export();
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_TRUE(r.damaged);
  EXPECT_EQ(r.bytes_skipped, static_cast<int64_t>(garbage.size() + last.size() - 9));
  const Csv poses = File("POSE_ULTRASOUND.csv");
  ASSERT_EQ(poses.rows.size(), 2u * kPosesPerSide);
  for (int k = 0; k < 2 * kPosesPerSide; ++k) {
    EXPECT_EQ(poses.rows[k].at("utime"), std::to_string(kT0 + k * 100'000)) << k;
  }
  const Csv damage = File(kCsvDamageFile);
  ASSERT_EQ(damage.rows.size(), 2u);
  EXPECT_EQ(damage.rows[0].at("offset"), std::to_string(garbage_offset));
  EXPECT_EQ(damage.rows[0].at("bytes"), std::to_string(garbage.size()));
  EXPECT_EQ(damage.rows[0].at("reason"), "not_an_event");
  EXPECT_EQ(damage.rows[0].at("recv_utime_before"),
            std::to_string(kT0 + (kPosesPerSide - 1) * 100'000 + kRecvLag_us));
  EXPECT_EQ(damage.rows[0].at("recv_utime_after"),
            std::to_string(kT0 + kPosesPerSide * 100'000 + kRecvLag_us));
  EXPECT_EQ(damage.rows[1].at("reason"), "truncated");
  EXPECT_EQ(damage.rows[1].at("recv_utime_after"), "");  // nothing after the end
}

TEST_F(CsvExportTest, RefusesAMissingLogAFileAsFolderAndAFolderWithFiles) {
  CsvExportOptions o;
  o.log_path = dir_.File("missing.lcm");
  o.out_dir = out_;
  EXPECT_FALSE(ExportLogToCsv(o).error.empty());
  EXPECT_FALSE(std::ifstream(out_).good());  // no folder left behind
  {
    auto log = NewLog();
    Put(log.get(), kT0, "POSE_FUSED", MakeTestPose(kT0, 1, 1.0, 2.0));
  }
  o.log_path = log_;
  o.out_dir = log_;  // a file
  EXPECT_NE(ExportLogToCsv(o).error.find("not a folder"), std::string::npos);
  o.out_dir = out_;
  ASSERT_TRUE(ExportLogToCsv(o).error.empty());
  EXPECT_NE(ExportLogToCsv(o).error.find("not empty"), std::string::npos);
  o.force = true;
  EXPECT_TRUE(ExportLogToCsv(o).error.empty());
  EXPECT_EQ(File("POSE_FUSED.csv").rows.size(), 1u);
}

}  // namespace
}  // namespace roomfix
