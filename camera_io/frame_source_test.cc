#include "camera_io/frame_source.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <random>
#include <string>
#include <vector>

#include "camera_io/jpeg_image.h"
#include "camera_io/v4l2_properties.h"
#include "tests/testing/test_paths.h"

namespace roomfix::camera {
namespace {

// Our decoder and OpenCV's imdecode are the same libjpeg-turbo; they differ
// only in the IDCT (IFAST here, ISLOW in OpenCV) and chroma upsampling
// (replication here, triangular in OpenCV), about one grey level on average
// on a real photo. Measured 0.2-0.56 (DecodeReducedOneMatchesImdecode prints
// it); ISLOW + triangular gives exactly imdecode's pixels.
constexpr double kDecoderMeanAbsTolerance = 1.0;
// Same decoder, same options, only cropped/skipped scanlines: identical.
constexpr double kRegionMeanAbsTolerance = 0.0;
// DCT scaling against the mean of scale x scale pixels (INTER_AREA): the
// scaled IDCT is a low-pass filter, not a box filter. Measured 0.17-0.48.
constexpr double kReducedMeanAbsTolerance = 1.0;

std::string SamplesDir() {
  const std::string shared = roomfix::testing::SharedDataDir();
  return shared.empty() ? "" : shared + "/opencv_samples";
}

#define REQUIRE_SAMPLES()                                                                    \
  if (SamplesDir().empty()) {                                                                \
    GTEST_SKIP() << "../shared/data is missing: the real images this test needs are absent"; \
  }

double MeanAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  EXPECT_EQ(a.size(), b.size());
  EXPECT_EQ(a.type(), b.type());
  if (a.size() != b.size() || a.type() != b.type() || a.empty()) return 1e9;
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  const cv::Scalar m = cv::mean(diff);
  return (m[0] + m[1] + m[2]) / 3.0;
}

std::vector<uint8_t> ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  std::vector<uint8_t> bytes(static_cast<size_t>(std::max<std::streamoff>(in.tellg(), 0)));
  in.seekg(0);
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return bytes;
}

void WriteBytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

// A real photo upscaled to 1920x1080 and encoded at quality 90 (4:2:0).
std::vector<uint8_t> HdJpeg() {
  cv::Mat photo = cv::imread(SamplesDir() + "/smarties.png", cv::IMREAD_COLOR);
  EXPECT_FALSE(photo.empty());
  cv::Mat hd;
  cv::resize(photo, hd, cv::Size(1920, 1080), 0, 0, cv::INTER_CUBIC);
  std::vector<uint8_t> bytes;
  cv::imencode(".jpg", hd, bytes, {cv::IMWRITE_JPEG_QUALITY, 90});
  return bytes;
}

// A detailed 1920x1080 frame: a 3 x 3 mosaic of the real 640x480 photos
// left01..left09 (chessboard, room, sensor noise), cropped, quality 90. Closer
// to a webcam frame's entropy than the smooth upscaled photo.
std::vector<uint8_t> HdMosaicJpeg() {
  cv::Mat mosaic(1440, 1920, CV_8UC3);
  for (int i = 0; i < 9; ++i) {
    cv::Mat photo =
        cv::imread(SamplesDir() + fmt::format("/left{:02d}.jpg", i + 1), cv::IMREAD_COLOR);
    EXPECT_EQ(photo.size(), cv::Size(640, 480));
    photo.copyTo(mosaic(cv::Rect((i % 3) * 640, (i / 3) * 480, 640, 480)));
  }
  std::vector<uint8_t> bytes;
  cv::imencode(".jpg", mosaic(cv::Rect(0, 0, 1920, 1080)), bytes, {cv::IMWRITE_JPEG_QUALITY, 90});
  return bytes;
}

std::unique_ptr<FrameImage> MustMake(std::vector<uint8_t> bytes,
                                     const JpegDecodeOptions& options = {}) {
  std::string error;
  auto image = MakeJpegImageWithOptions(std::move(bytes), options, &error);
  EXPECT_NE(image, nullptr) << error;
  return image;
}

TEST(JpegImage, ReadsOnlyTheHeader) {
  REQUIRE_SAMPLES();
  const std::vector<uint8_t> bytes = ReadBytes(SamplesDir() + "/left01.jpg");
  auto image = MustMake(bytes);
  ASSERT_NE(image, nullptr);
  EXPECT_TRUE(image->encoded());
  EXPECT_EQ(image->width_px(), 640);
  EXPECT_EQ(image->height_px(), 480);
  // The bytes as given, for roomfix grab to save unchanged. (Read once:
  // a second virtual call is one GCC 12 at -O3 cannot prove non-null,
  // -Wnull-dereference.)
  const std::vector<uint8_t>* kept = image->jpeg_bytes();
  ASSERT_NE(kept, nullptr);
  EXPECT_TRUE(std::equal(kept->begin(), kept->end(), bytes.begin(), bytes.end()));
}

TEST(JpegImage, DecodeReducedOneMatchesImdecode) {
  REQUIRE_SAMPLES();
  for (const std::string& name :
       {std::string("hd smarties"), std::string("hd mosaic"), std::string("left01.jpg")}) {
    const std::vector<uint8_t> bytes = name == "hd smarties" ? HdJpeg()
                                       : name == "hd mosaic" ? HdMosaicJpeg()
                                                             : ReadBytes(SamplesDir() + "/" + name);
    const cv::Mat reference = cv::imdecode(bytes, cv::IMREAD_COLOR);
    for (const bool fast : {true, false}) {
      for (const bool fancy : {false, true}) {
        auto image = MustMake(bytes, JpegDecodeOptions{fast, fancy});
        ASSERT_NE(image, nullptr);
        cv::Mat full;
        std::string error;
        ASSERT_TRUE(image->DecodeReduced(1, &full, &error)) << error;
        const double diff = MeanAbsDiff(full, reference);
        std::printf("%-12s dct %-5s upsampling %-11s mean |ours - imdecode| = %.3f\n", name.c_str(),
                    fast ? "IFAST" : "ISLOW", fancy ? "triangular" : "replicate", diff);
        EXPECT_LE(diff, kDecoderMeanAbsTolerance);
        if (!fast && fancy) {
          EXPECT_EQ(diff, 0.0) << "same libjpeg, same options";
        }
      }
    }
  }
}

TEST(JpegImage, DecodeRegionMatchesFullDecode) {
  REQUIRE_SAMPLES();
  for (const auto& bytes : {HdJpeg(), HdMosaicJpeg()}) {
    for (const bool fancy : {false, true}) {
      auto image = MustMake(bytes, JpegDecodeOptions{true, fancy});
      ASSERT_NE(image, nullptr);
      cv::Mat full;
      std::string error;
      ASSERT_TRUE(image->DecodeReduced(1, &full, &error)) << error;
      const cv::Rect whole(0, 0, 1920, 1080);
      const std::vector<cv::Rect> rects = {
          {0, 0, 200, 200},      {1720, 880, 200, 200},  {860, 440, 200, 200},
          {333, 517, 101, 77},   {1, 1, 1, 1},           {7, 9, 15, 3},
          {-50, -30, 200, 200},  {1800, 1000, 300, 300}, {1919, 1079, 5, 5},
          {0, 0, 1920, 1080},    {0, 1079, 1920, 1},     {17, 0, 1, 1080},
          {-10, -10, 2000, 1200}};
      for (const cv::Rect& rect : rects) {
        cv::Mat region;
        ASSERT_TRUE(image->DecodeRegion(rect, &region, &error)) << error;
        const cv::Rect clipped = rect & whole;
        ASSERT_EQ(region.size(), clipped.size()) << rect;
        const double diff = MeanAbsDiff(region, full(clipped));
        // Triangular upsampling uses the neighbouring chroma column, which the
        // crop can cut at its iMCU boundary: allow a little there.
        EXPECT_LE(diff, fancy ? 0.5 : kRegionMeanAbsTolerance) << rect << " fancy " << fancy;
      }
      cv::Mat outside;
      ASSERT_TRUE(image->DecodeRegion(cv::Rect(3000, 10, 50, 50), &outside, &error));
      EXPECT_TRUE(outside.empty());
    }
  }
}

TEST(JpegImage, DecodeReducedIsCloseToAreaResize) {
  REQUIRE_SAMPLES();
  // The HD frame and an odd-sized real photo (sizes round up).
  cv::Mat left = cv::imread(SamplesDir() + "/left02.jpg", cv::IMREAD_COLOR);
  cv::Mat odd = left(cv::Rect(0, 0, 637, 477)).clone();
  std::vector<uint8_t> odd_bytes;
  cv::imencode(".jpg", odd, odd_bytes, {cv::IMWRITE_JPEG_QUALITY, 90});
  for (const auto& bytes : {HdJpeg(), HdMosaicJpeg(), odd_bytes}) {
    auto image = MustMake(bytes);
    ASSERT_NE(image, nullptr);
    cv::Mat full;
    std::string error;
    ASSERT_TRUE(image->DecodeReduced(1, &full, &error)) << error;
    for (const int scale : {2, 4, 8}) {
      cv::Mat reduced;
      ASSERT_TRUE(image->DecodeReduced(scale, &reduced, &error)) << error;
      const cv::Size expected((full.cols + scale - 1) / scale, (full.rows + scale - 1) / scale);
      ASSERT_EQ(reduced.size(), expected);
      // Each output pixel against the mean of its scale x scale block (the
      // partial blocks at the right and bottom padded by replication, as the
      // encoder pads them): what MakeDecodedImage gives.
      cv::Mat area;
      ASSERT_TRUE(MakeDecodedImage(full)->DecodeReduced(scale, &area, &error)) << error;
      const double diff = MeanAbsDiff(reduced, area);
      std::printf("%dx%d scale %d: mean |DCT scaled - INTER_AREA| = %.3f\n", full.cols, full.rows,
                  scale, diff);
      EXPECT_LE(diff, kReducedMeanAbsTolerance);
    }
    cv::Mat unused;
    EXPECT_FALSE(image->DecodeReduced(3, &unused, &error));
    EXPECT_NE(error.find("scale"), std::string::npos);
  }
}

bool MentionsTruncation(std::string message) {
  std::transform(message.begin(), message.end(), message.begin(), ::tolower);
  return message.find("premature end") != std::string::npos ||
         message.find("truncated") != std::string::npos;
}

TEST(JpegImage, TruncatedBodyFailsAtDecode) {
  REQUIRE_SAMPLES();
  std::vector<uint8_t> bytes = HdJpeg();
  bytes.resize(bytes.size() * 6 / 10);
  EXPECT_FALSE(JpegHasEndMarker(bytes));
  std::string error;
  auto image = MakeJpegImage(bytes, &error);
  ASSERT_NE(image, nullptr) << "the header is intact: " << error;
  cv::Mat out;
  EXPECT_FALSE(image->DecodeReduced(1, &out, &error));
  EXPECT_TRUE(MentionsTruncation(error)) << error;
  error.clear();
  EXPECT_FALSE(image->DecodeReduced(4, &out, &error));
  EXPECT_TRUE(MentionsTruncation(error)) << error;
  error.clear();
  EXPECT_FALSE(image->DecodeRegion(cv::Rect(860, 1000, 200, 80), &out, &error));
  EXPECT_TRUE(MentionsTruncation(error)) << error;
  std::printf("truncated: %s\n", error.c_str());
  // The top of the frame is still there, and decodes.
  EXPECT_TRUE(image->DecodeRegion(cv::Rect(0, 0, 200, 100), &out, &error)) << error;
}

TEST(JpegImage, CorruptBodyFailsWithoutCrashing) {
  REQUIRE_SAMPLES();
  const std::vector<uint8_t> good = ReadBytes(SamplesDir() + "/left04.jpg");
  std::mt19937 rng(11);
  int failed = 0;
  for (int trial = 0; trial < 40; ++trial) {
    std::vector<uint8_t> bytes = good;
    // Overwrite a run of the entropy-coded body (after the first 700 header bytes).
    const size_t at = 700 + rng() % (bytes.size() - 900);
    for (size_t i = at; i < at + 64; ++i) bytes[i] = static_cast<uint8_t>(rng());
    std::string error;
    auto image = MakeJpegImage(bytes, &error);
    if (image == nullptr) continue;
    cv::Mat out;
    const bool reduced = image->DecodeReduced(2, &out, &error);
    const bool region = image->DecodeRegion(cv::Rect(100, 100, 300, 300), &out, &error);
    if (!reduced) {
      ++failed;
      EXPECT_FALSE(error.empty());
    }
    (void)region;
  }
  // Most corruptions are caught (libjpeg warns of corrupt data); none crash.
  std::printf("corrupted bodies refused at decode: %d of 40\n", failed);
  EXPECT_GT(failed, 20);
}

TEST(JpegImage, RefusesRandomAndEmptyData) {
  std::mt19937 rng(7);
  std::vector<uint8_t> noise(5000);
  for (auto& b : noise) b = static_cast<uint8_t>(rng());
  std::string error;
  EXPECT_EQ(MakeJpegImage(noise, &error), nullptr);
  EXPECT_FALSE(error.empty());
  std::printf("random bytes: %s\n", error.c_str());
  error.clear();
  EXPECT_EQ(MakeJpegImage({}, &error), nullptr);
  EXPECT_NE(error.find("empty"), std::string::npos) << error;
}

TEST(JpegImage, RefusesTruncatedHeader) {
  REQUIRE_SAMPLES();
  std::vector<uint8_t> bytes = ReadBytes(SamplesDir() + "/left01.jpg");
  bytes.resize(100);
  std::string error;
  EXPECT_EQ(MakeJpegImage(bytes, &error), nullptr);
  EXPECT_TRUE(MentionsTruncation(error)) << error;
}

TEST(DecodedImage, ViewsAndAreaReduction) {
  cv::Mat bgr(101, 203, CV_8UC3, cv::Scalar(10, 20, 30));
  auto image = MakeDecodedImage(bgr);
  EXPECT_FALSE(image->encoded());
  EXPECT_EQ(image->jpeg_bytes(), nullptr);
  EXPECT_EQ(image->width_px(), 203);
  cv::Mat out;
  std::string error;
  ASSERT_TRUE(image->DecodeReduced(4, &out, &error));
  EXPECT_EQ(out.size(), cv::Size(51, 26));
  EXPECT_EQ(out.at<cv::Vec3b>(0, 0), cv::Vec3b(10, 20, 30));
  ASSERT_TRUE(image->DecodeRegion(cv::Rect(200, 100, 10, 10), &out, &error));
  EXPECT_EQ(out.size(), cv::Size(3, 1));
  auto grey = MakeDecodedImage(cv::Mat(5, 5, CV_8UC1, cv::Scalar(7)));
  ASSERT_TRUE(grey->DecodeReduced(1, &out, &error));
  EXPECT_EQ(out.type(), CV_8UC3);
}

// ------------------------------------------------------------ frame sources

std::vector<std::string> LeftJpegs(int n) {
  std::vector<std::string> names;
  for (int i = 1; i <= n; ++i) {
    names.push_back(fmt::format("left{:02d}.jpg", i));
  }
  return names;
}

TEST(ImageFilesSource, ReadsAFolderSortedWithVirtualTime) {
  REQUIRE_SAMPLES();
  roomfix::testing::TempDir dir;
  const auto names = LeftJpegs(4);
  for (const auto& name : names) WriteBytes(dir.File(name), ReadBytes(SamplesDir() + "/" + name));
  cv::imwrite(dir.File("left05.png"), cv::imread(SamplesDir() + "/left05.jpg"));
  CaptureSettings settings;
  settings.fps = 4.0;
  settings.start_utime = 1000000;
  std::string error;
  auto source = MakeFrameSource(dir.path(), settings, &error);
  ASSERT_NE(source, nullptr) << error;
  ASSERT_TRUE(source->Open(&error)) << error;
  EXPECT_FALSE(source->live());
  EXPECT_NE(source->Describe().find("5 files"), std::string::npos) << source->Describe();
  for (int i = 0; i < 5; ++i) {
    Frame frame;
    ASSERT_EQ(source->Read(&frame, &error), ReadStatus::kFrame) << error;
    EXPECT_EQ(frame.seq, i);
    EXPECT_EQ(frame.capture_utime, 1000000 + i * 250000);
    EXPECT_EQ(frame.image->encoded(), i < 4);
    EXPECT_EQ(frame.image->width_px(), 640);
    cv::Mat small;
    EXPECT_TRUE(frame.image->DecodeReduced(2, &small, &error)) << error;
  }
  Frame frame;
  EXPECT_EQ(source->Read(&frame, &error), ReadStatus::kEndOfStream);
}

TEST(ImageFilesSource, ReadsAGlobAndLoops) {
  REQUIRE_SAMPLES();
  roomfix::testing::TempDir dir;
  for (const auto& name : LeftJpegs(3)) {
    WriteBytes(dir.File(name), ReadBytes(SamplesDir() + "/" + name));
  }
  WriteBytes(dir.File("notes.txt"), {'h', 'i'});
  CaptureSettings settings;
  settings.loop = true;
  std::string error;
  auto source = MakeFrameSource(dir.path() + "/left*.jpg", settings, &error);
  ASSERT_NE(source, nullptr) << error;
  ASSERT_TRUE(source->Open(&error)) << error;
  for (int i = 0; i < 7; ++i) {
    Frame frame;
    ASSERT_EQ(source->Read(&frame, &error), ReadStatus::kFrame) << error;
    EXPECT_EQ(frame.seq, i);
  }
  auto none = MakeFrameSource(dir.path() + "/*.bmp", settings, &error);
  ASSERT_NE(none, nullptr);
  EXPECT_FALSE(none->Open(&error));
  EXPECT_NE(error.find("*.bmp"), std::string::npos) << error;
}

TEST(ImageFilesSource, ReportsBadFilesAndGoesOn) {
  REQUIRE_SAMPLES();
  roomfix::testing::TempDir dir;
  WriteBytes(dir.File("a.jpg"), ReadBytes(SamplesDir() + "/left01.jpg"));
  std::vector<uint8_t> truncated = ReadBytes(SamplesDir() + "/left02.jpg");
  truncated.resize(truncated.size() * 6 / 10);
  WriteBytes(dir.File("b.jpg"), truncated);
  WriteBytes(dir.File("c.jpg"), {});
  WriteBytes(dir.File("d.png"), {'n', 'o', 't', ' ', 'a', 'n', ' ', 'i', 'm', 'a', 'g', 'e'});
  WriteBytes(dir.File("e.jpg"), ReadBytes(SamplesDir() + "/left03.jpg"));
  CaptureSettings settings;
  std::string error;
  auto source = MakeFrameSource(dir.path(), settings, &error);
  ASSERT_TRUE(source->Open(&error)) << error;
  const std::vector<std::pair<ReadStatus, std::string>> expected = {
      {ReadStatus::kFrame, ""},
      {ReadStatus::kBadFrame, "b.jpg: truncated"},
      {ReadStatus::kBadFrame, "c.jpg: empty file"},
      {ReadStatus::kBadFrame, "d.png: not an image format read here"},
      {ReadStatus::kFrame, ""},
      {ReadStatus::kEndOfStream, ""}};
  for (size_t i = 0; i < expected.size(); ++i) {
    Frame frame;
    error.clear();
    EXPECT_EQ(source->Read(&frame, &error), expected[i].first) << i << " " << error;
    if (expected[i].first == ReadStatus::kBadFrame) {
      EXPECT_NE(error.find(expected[i].second), std::string::npos) << error;
      std::printf("bad frame %lld: %s\n", static_cast<long long>(frame.seq), error.c_str());
    }
    if (expected[i].first != ReadStatus::kEndOfStream) {
      EXPECT_EQ(frame.seq, static_cast<int64_t>(i));
    }
  }
}

// camera_proc counts a bad frame under the kind the source reports with it
// (Frame::problem), decided where the failure is seen: libjpeg's message
// code, the header reader, the size check. A file's name never decides it.
TEST(ImageFilesSource, SaysWhyAFrameIsBadAsAValue) {
  REQUIRE_SAMPLES();
  roomfix::testing::TempDir dir;
  const std::vector<uint8_t> good = ReadBytes(SamplesDir() + "/left01.jpg");
  std::vector<uint8_t> no_end_marker = good;
  no_end_marker.resize(good.size() * 6 / 10);
  // A header cut short, closed by an end marker: libjpeg runs out of data
  // inside the header (JWRN_JPEG_EOF), not at the cheap end-marker check.
  std::vector<uint8_t> header_cut(good.begin(), good.begin() + 100);
  header_cut.push_back(0xFF);
  header_cut.push_back(0xD9);
  WriteBytes(dir.File("a_truncated_empty.png"), {'n', 'o', 't', ' ', 'a', 'n', ' ', 'i', 'm'});
  WriteBytes(dir.File("b.jpg"), no_end_marker);
  WriteBytes(dir.File("c.jpg"), header_cut);
  WriteBytes(dir.File("d.jpg"), {});
  // A PNG header stating 65536 x 65536 px, over the camera's 1920 x 1080.
  WriteBytes(dir.File("e.png"),
             {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n', 0, 0, 0, 13, 'I', 'H', 'D',
              'R',  0,   1,   0,   0,    0,    1,    0,    0, 8, 2, 0,  0,   0});
  WriteBytes(dir.File("f.png"), {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n', 0, 0, 0, 13});
  CaptureSettings settings;
  std::string error;
  auto source = MakeFrameSource(dir.path(), settings, &error);
  ASSERT_TRUE(source->Open(&error)) << error;
  const std::vector<FrameProblem> expected = {FrameProblem::kUnreadable, FrameProblem::kTruncated,
                                              FrameProblem::kTruncated,  FrameProblem::kEmpty,
                                              FrameProblem::kWrongSize,  FrameProblem::kTruncated};
  for (size_t i = 0; i < expected.size(); ++i) {
    Frame frame;
    ASSERT_EQ(source->Read(&frame, &error), ReadStatus::kBadFrame) << i;
    EXPECT_EQ(frame.problem, expected[i]) << i << " " << error;
  }
  EXPECT_STREQ(FrameProblemCounter(FrameProblem::kWrongSize), "wrong_frame_size");
  EXPECT_STREQ(FrameProblemCounter(FrameProblem::kTruncated), "truncated_frame");
}

TEST(ImageFilesSource, PacesInRealTime) {
  REQUIRE_SAMPLES();
  roomfix::testing::TempDir dir;
  for (const auto& name : LeftJpegs(3)) {
    WriteBytes(dir.File(name), ReadBytes(SamplesDir() + "/" + name));
  }
  CaptureSettings settings;
  settings.realtime = true;
  settings.fps = 20.0;
  std::string error;
  auto source = MakeFrameSource(dir.path(), settings, &error);
  ASSERT_TRUE(source->Open(&error)) << error;
  std::vector<int64_t> stamps;
  for (int i = 0; i < 3; ++i) {
    Frame frame;
    ASSERT_EQ(source->Read(&frame, &error), ReadStatus::kFrame) << error;
    stamps.push_back(frame.capture_utime);
  }
  // Paced to 50 ms: never early (a late wake-up is allowed).
  EXPECT_GE(stamps[2] - stamps[0], 100000 - 1000);
}

TEST(VideoFileSource, ReadsAnMjpegAviAndLoops) {
  REQUIRE_SAMPLES();
  roomfix::testing::TempDir dir;
  const std::string path = dir.File("run.avi");
  {
    cv::VideoWriter writer(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 30.0,
                           cv::Size(640, 480));
    ASSERT_TRUE(writer.isOpened());
    for (const auto& name : LeftJpegs(9)) writer.write(cv::imread(SamplesDir() + "/" + name));
  }
  CaptureSettings settings;
  settings.fps = 30.0;
  std::string error;
  auto source = MakeFrameSource(path, settings, &error);
  ASSERT_NE(source, nullptr);
  ASSERT_TRUE(source->Open(&error)) << error;
  std::printf("%s\n", source->Describe().c_str());
  const cv::Mat first_reference = cv::imread(SamplesDir() + "/left01.jpg");
  int frames = 0;
  bool encoded = false;
  for (;;) {
    Frame frame;
    const ReadStatus status = source->Read(&frame, &error);
    if (status == ReadStatus::kEndOfStream) break;
    ASSERT_EQ(status, ReadStatus::kFrame) << error;
    EXPECT_EQ(frame.seq, frames);
    EXPECT_EQ(frame.capture_utime, std::llround(frames * 1e6 / 30.0));
    encoded = frame.image->encoded();
    cv::Mat full;
    ASSERT_TRUE(frame.image->DecodeReduced(1, &full, &error)) << error;
    ASSERT_EQ(full.size(), cv::Size(640, 480));
    if (frames == 0) {
      EXPECT_LE(MeanAbsDiff(full, first_reference), 8.0);
    }
    ++frames;
    ASSERT_LT(frames, 100);
  }
  EXPECT_EQ(frames, 9);
  std::printf("MJPEG avi: %d frames, read %s\n", frames,
              encoded ? "compressed (FFmpeg raw mode)" : "decoded (raw mode not available)");
  EXPECT_TRUE(encoded) << "FFmpeg raw mode (CAP_PROP_FORMAT = -1) was expected to work";

  settings.loop = true;
  auto looping = MakeFrameSource(path, settings, &error);
  ASSERT_TRUE(looping->Open(&error)) << error;
  for (int i = 0; i < 20; ++i) {
    Frame frame;
    ASSERT_EQ(looping->Read(&frame, &error), ReadStatus::kFrame) << i << " " << error;
    EXPECT_EQ(frame.seq, i);
  }
}

TEST(VideoFileSource, MissingFileFailsToOpen) {
  std::string error;
  auto source = MakeFrameSource("/nonexistent/run.avi", CaptureSettings{}, &error);
  ASSERT_NE(source, nullptr);
  EXPECT_FALSE(source->Open(&error));
  EXPECT_NE(error.find("/nonexistent/run.avi"), std::string::npos) << error;
  EXPECT_NE(error.find("no such file"), std::string::npos) << error;
}

TEST(V4l2Source, MissingDeviceFailsToOpen) {
  std::string error;
  auto source = MakeFrameSource("/dev/video99", CaptureSettings{}, &error);
  ASSERT_NE(source, nullptr);
  EXPECT_TRUE(source->live());
  EXPECT_FALSE(source->Open(&error));
  EXPECT_EQ(error, "cannot open /dev/video99: no such device");
  auto by_number = MakeFrameSource("99", CaptureSettings{}, &error);
  ASSERT_NE(by_number, nullptr);
  EXPECT_FALSE(by_number->Open(&error));
  EXPECT_EQ(error, "cannot open /dev/video99: no such device");
  EXPECT_EQ(MakeFrameSource("", CaptureSettings{}, &error), nullptr);
}

TEST(CaptureProperties, ReportsRefusedChangedAndUnknown) {
  // A fake camera: no gamma or focus control, exposure clamped to 250, auto
  // exposure must be manual (1) before exposure takes, and automatic white
  // balance off (0) before a temperature does.
  std::map<int, double> controls = {{cv::CAP_PROP_BRIGHTNESS, 0},
                                    {cv::CAP_PROP_EXPOSURE, 100},
                                    {cv::CAP_PROP_AUTO_EXPOSURE, 3},
                                    {cv::CAP_PROP_AUTO_WB, 1},
                                    {cv::CAP_PROP_WB_TEMPERATURE, 6500}};
  std::vector<std::pair<int, double>> calls;
  auto set = [&](int id, double value) {
    calls.emplace_back(id, value);
    if (controls.count(id) == 0) return false;
    if (id == cv::CAP_PROP_EXPOSURE) {
      if (controls[cv::CAP_PROP_AUTO_EXPOSURE] != 1) return true;  // ignored in auto mode
      value = std::max(value, 250.0);
    }
    if (id == cv::CAP_PROP_WB_TEMPERATURE && controls[cv::CAP_PROP_AUTO_WB] != 0) return true;
    controls[id] = value;
    return true;
  };
  auto get = [&](int id) { return controls.count(id) != 0 ? controls[id] : -1.0; };
  const auto refused = ApplyCaptureProperties({{"brightness", 40},
                                               {"exposure", 156},
                                               {"gamma", 100},
                                               {"focus", 3},
                                               {"white_balance", 4000},
                                               {"zoom", 2}},
                                              set, get);
  const std::vector<std::string> expected = {"exposure: asked 156, got 250",
                                             "focus: cannot turn autofocus off",
                                             "gamma: not supported", "zoom: unknown property"};
  EXPECT_EQ(refused, expected);
  EXPECT_EQ(controls[cv::CAP_PROP_AUTO_WB], 0);
  EXPECT_EQ(controls[cv::CAP_PROP_WB_TEMPERATURE], 4000);
  EXPECT_EQ(controls[cv::CAP_PROP_AUTO_EXPOSURE], 1);
  EXPECT_EQ(controls[cv::CAP_PROP_BRIGHTNESS], 40);
  // Auto exposure went to manual before the exposure was set.
  const auto manual = std::find(calls.begin(), calls.end(),
                                std::make_pair(static_cast<int>(cv::CAP_PROP_AUTO_EXPOSURE), 1.0));
  const auto exposure = std::find(calls.begin(), calls.end(),
                                  std::make_pair(static_cast<int>(cv::CAP_PROP_EXPOSURE), 156.0));
  EXPECT_LT(manual, exposure);
  EXPECT_TRUE(ApplyCaptureProperties({{"brightness", 40}}, set, get).empty());
}

}  // namespace
}  // namespace roomfix::camera
