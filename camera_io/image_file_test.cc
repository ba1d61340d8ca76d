// Image files from outside are size-checked from their header before any
// decoding, and image outputs report a failed write.
#include "camera_io/image_file.h"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include <chrono>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "camera_io/frame_source.h"
#include "tests/testing/test_images.h"
#include "tests/testing/test_paths.h"

namespace roomfix::camera {
namespace {

using roomfix::testing::TempDir;

// What the refusal of a huge image may cost: reading its few hundred KB
// of file. Decoding the 20000 x 20000 PNG would take 1.2 GB as BGR.
constexpr double kMaxPeakGrowthMb = 64.0;

void WriteBytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
}

double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

std::vector<uint8_t> Encode(const std::string& ext, int width, int height) {
  const cv::Mat image(height, width, CV_8UC3, cv::Scalar(10, 200, 30));
  std::vector<uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(ext, image, bytes)) << ext;
  return bytes;
}

TEST(ReadImageHeader, ReadsTheSizeOfEveryFormatOpenCvWritesHere) {
  for (const std::string ext : {".png", ".jpg", ".bmp", ".ppm"}) {
    const std::vector<uint8_t> bytes = Encode(ext, 321, 123);
    ImageHeader h;
    std::string error;
    ASSERT_TRUE(ReadImageHeader(bytes.data(), bytes.size(), &h, &error)) << ext << ": " << error;
    EXPECT_EQ(h.width_px, 321) << ext;
    EXPECT_EQ(h.height_px, 123) << ext;
  }
}

TEST(ReadImageHeader, RefusesFormatsItCannotCheckAndTruncatedHeaders) {
  ImageHeader h;
  std::string error;
  const std::vector<uint8_t> tiff = Encode(".tiff", 10, 10);
  EXPECT_FALSE(ReadImageHeader(tiff.data(), tiff.size(), &h, &error));
  EXPECT_EQ(error, "not an image format read here (PNG, JPEG, BMP, PNM)");
  const std::vector<uint8_t> png = Encode(".png", 10, 10);
  EXPECT_FALSE(ReadImageHeader(png.data(), 20, &h, &error));
  EXPECT_EQ(error, "truncated PNG header (no IHDR chunk)");
  const std::vector<uint8_t> jpeg = Encode(".jpg", 10, 10);
  EXPECT_FALSE(ReadImageHeader(jpeg.data(), 40, &h, &error));
  EXPECT_EQ(error, "not a readable JPEG: Premature end of JPEG file");
  const std::vector<uint8_t> zero_width = roomfix::testing::ForgedPngHeader(0, 10);
  EXPECT_FALSE(ReadImageHeader(zero_width.data(), zero_width.size(), &h, &error));
  EXPECT_EQ(error, "PNG header states 0 x 10 px");
}

TEST(DecodeImageChecked, RefusesTheForged57BytePngUndecoded) {
  const std::vector<uint8_t> forged = roomfix::testing::ForgedPngHeader(100000, 100000);
  ASSERT_EQ(forged.size(), 57u);
  // Why the check: OpenCV itself throws on it (over its own 1 gigapixel
  // limit), which killed camera_proc with SIGABRT.
  EXPECT_THROW(cv::imdecode(forged, cv::IMREAD_COLOR), cv::Exception);
  cv::Mat image;
  std::string error;
  EXPECT_FALSE(DecodeImageChecked(forged, 1920, 1080, cv::IMREAD_COLOR, &image, &error));
  EXPECT_EQ(error,
            "PNG of 100000 x 100000 px is larger than the limit of 1920 x 1080 px (not decoded)");
  EXPECT_TRUE(image.empty());
}

// The attack found after the first fix: a real small JPEG whose frame header
// is patched to 20000 x 20000, behind SOI and a two-byte marker with no
// length (TEM, FF 01) or stray bytes (FF 00). A walk of the segments by hand
// reads the next marker's bytes as a length, lands at byte 65508, and finds a
// dummy 16 x 16 frame header placed there; libjpeg reads the real one and
// OpenCV decodes 1.2 GB from a 65 KB file. The size must come from libjpeg.
std::vector<uint8_t> JpegHidingItsSize(uint8_t marker_without_length) {
  std::vector<uint8_t> real = Encode(".jpg", 64, 48);
  for (size_t i = 2; i + 9 <= real.size(); ++i) {
    if (real[i] == 0xFF && real[i + 1] == 0xC0) {  // baseline SOF0: patch the size
      real[i + 5] = 20000 >> 8;
      real[i + 6] = 20000 & 0xFF;
      real[i + 7] = 20000 >> 8;
      real[i + 8] = 20000 & 0xFF;
      break;
    }
  }
  std::vector<uint8_t> out(real.size() + 2);
  out[0] = 0xFF;
  out[1] = 0xD8;
  out[2] = 0xFF;
  out[3] = marker_without_length;
  std::copy(real.begin() + 2, real.end(), out.begin() + 4);  // APP0 (FF E0) next
  constexpr size_t kDummyAt = 2 + 2 + 0xFFE0;                // where a naive walk lands
  EXPECT_LT(out.size(), kDummyAt);
  out.resize(kDummyAt, 0);
  const uint8_t dummy_sof[] = {0xFF, 0xC0, 0x00, 0x11, 0x08, 0x00, 0x10, 0x00, 0x10};
  out.insert(out.end(), std::begin(dummy_sof), std::end(dummy_sof));
  out.resize(out.size() + 16, 0);
  return out;
}

TEST(ReadImageHeader, TakesAJpegsSizeFromLibjpegNotFromADummyHeader) {
  const std::vector<uint8_t> tem = JpegHidingItsSize(0x01);
  ImageHeader header;
  std::string error;
  // libjpeg's header reader sees the real 20000 x 20000 and refuses it
  // outright (over 2^27 pixels), before any caller's own limit.
  EXPECT_FALSE(ReadImageHeader(tem.data(), tem.size(), &header, &error));
  EXPECT_EQ(error, "not a readable JPEG: JPEG image size out of range (20000 x 20000 px)");
  cv::Mat image;
  EXPECT_FALSE(DecodeImageChecked(tem, 8192, 8192, cv::IMREAD_COLOR, &image, &error));
  EXPECT_TRUE(image.empty());
  // Stray bytes are a libjpeg warning, and its warnings are errors here.
  const std::vector<uint8_t> stray = JpegHidingItsSize(0x00);
  EXPECT_FALSE(ReadImageHeader(stray.data(), stray.size(), &header, &error));
  EXPECT_EQ(error.rfind("not a readable JPEG", 0), 0u) << error;
}

TEST(DecodeImageChecked, DecodesAnImageAtTheLimitAndCatchesOpenCvErrors) {
  const std::vector<uint8_t> png = Encode(".png", 64, 48);
  cv::Mat image;
  std::string error;
  ASSERT_TRUE(DecodeImageChecked(png, 64, 48, cv::IMREAD_COLOR, &image, &error)) << error;
  EXPECT_EQ(image.size(), cv::Size(64, 48));
  EXPECT_EQ(image.at<cv::Vec3b>(10, 10), cv::Vec3b(10, 200, 30));
  // The header of a real image with its body cut: OpenCV fails, we report.
  std::vector<uint8_t> cut(png.begin(), png.begin() + 40);
  EXPECT_FALSE(DecodeImageChecked(cut, 64, 48, cv::IMREAD_COLOR, &image, &error));
  EXPECT_EQ(error.rfind("not a readable PNG image", 0), 0u) << error;
}

TEST(ReadImageChecked, RefusesALargeRealPngFromItsHeaderWithoutDecoding) {
  TempDir dir;
  const std::string path = dir.File("huge.png");
  ASSERT_TRUE(roomfix::testing::WriteOneColourPng(path, 20000, 20000));
  struct stat st {};
  ASSERT_EQ(stat(path.c_str(), &st), 0);
  std::printf("20000 x 20000 one-colour PNG: %lld bytes\n", static_cast<long long>(st.st_size));
  EXPECT_LT(st.st_size, 2 << 20) << "the test image should stay small on disk";
  const double before_mb = PeakRssMb();
  cv::Mat image;
  std::string error;
  EXPECT_FALSE(ReadImageChecked(path, kMaxToolImageSidePx, kMaxToolImageSidePx, cv::IMREAD_COLOR,
                                &image, &error));
  EXPECT_EQ(error, path +
                       ": PNG of 20000 x 20000 px is larger than the limit of 8192 x 8192 px (not "
                       "decoded)");
  EXPECT_LT(PeakRssMb() - before_mb, kMaxPeakGrowthMb);
  // The same file is a real PNG: a small one made the same way decodes.
  ASSERT_TRUE(roomfix::testing::WriteOneColourPng(dir.File("small.png"), 300, 200, 77));
  ASSERT_TRUE(
      ReadImageChecked(dir.File("small.png"), 300, 200, cv::IMREAD_GRAYSCALE, &image, &error))
      << error;
  EXPECT_EQ(image.size(), cv::Size(300, 200));
  EXPECT_EQ(image.at<uint8_t>(100, 100), 77);
}

TEST(ReadImageBytes, RefusesFoldersFifosAndDevicesWithoutBlocking) {
  TempDir dir;
  ASSERT_EQ(mkfifo(dir.File("fifo.png").c_str(), 0600), 0);
  std::vector<uint8_t> bytes;
  std::string error;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(ReadImageBytes(dir.File("fifo.png"), &bytes, &error));
  EXPECT_EQ(error, "not a regular file");
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
  EXPECT_FALSE(ReadImageBytes("/dev/zero", &bytes, &error));
  EXPECT_EQ(error, "not a regular file");
  EXPECT_FALSE(ReadImageBytes(dir.path(), &bytes, &error));
  EXPECT_EQ(error, "not a regular file (a folder)");
}

TEST(ImageFilesSource, CountsOversizeFramesAsBadAndGoesOnWithoutDecodingThem) {
  TempDir dir;
  // Sorted: a good frame, the forged header, the large real PNG, a good one.
  const cv::Mat frame(1080, 1920, CV_8UC3, cv::Scalar(40, 40, 40));
  ASSERT_TRUE(cv::imwrite(dir.File("a_good.png"), frame));
  WriteBytes(dir.File("b_forged.png"), roomfix::testing::ForgedPngHeader(100000, 100000));
  ASSERT_TRUE(roomfix::testing::WriteOneColourPng(dir.File("c_huge.png"), 20000, 20000));
  ASSERT_TRUE(cv::imwrite(dir.File("d_good.jpg"), frame));
  CaptureSettings settings;  // 1920 x 1080
  std::string error;
  auto source = MakeFrameSource(dir.path(), settings, &error);
  ASSERT_NE(source, nullptr) << error;
  ASSERT_TRUE(source->Open(&error)) << error;
  const double before_mb = PeakRssMb();
  Frame f;
  ASSERT_EQ(source->Read(&f, &error), ReadStatus::kFrame) << error;
  EXPECT_EQ(f.image->width_px(), 1920);
  EXPECT_EQ(source->Read(&f, &error), ReadStatus::kBadFrame);
  EXPECT_EQ(error, dir.File("b_forged.png") +
                       ": PNG of 100000 x 100000 px is larger than the limit of the camera's "
                       "1920 x 1080 px (not decoded)");
  EXPECT_EQ(source->Read(&f, &error), ReadStatus::kBadFrame);
  EXPECT_NE(error.find("c_huge.png: PNG of 20000 x 20000 px is larger than the limit"),
            std::string::npos)
      << error;
  ASSERT_EQ(source->Read(&f, &error), ReadStatus::kFrame) << error;
  EXPECT_TRUE(f.image->encoded());
  EXPECT_EQ(source->Read(&f, &error), ReadStatus::kEndOfStream);
  // One 1920 x 1080 BGR frame is 6 MB; the refused ones cost nothing.
  EXPECT_LT(PeakRssMb() - before_mb, kMaxPeakGrowthMb);
}

TEST(WriteImageChecked, ReportsAFullDeviceAndWritesARealFile) {
  const cv::Mat image(48, 64, CV_8UC3, cv::Scalar(1, 2, 3));
  std::string error;
  EXPECT_FALSE(WriteImageChecked("/dev/full", image, &error));
  EXPECT_EQ(error, "/dev/full: cannot write: No space left on device");
  TempDir dir;
  ASSERT_TRUE(WriteImageChecked(dir.File("x.png"), image, &error)) << error;
  const cv::Mat back = cv::imread(dir.File("x.png"));
  EXPECT_EQ(back.size(), image.size());
  EXPECT_EQ(back.at<cv::Vec3b>(5, 5), cv::Vec3b(1, 2, 3));
  EXPECT_FALSE(WriteImageChecked(dir.File("x.notanimage"), image, &error));
  EXPECT_NE(error.find("cannot write"), std::string::npos) << error;
}

}  // namespace
}  // namespace roomfix::camera
