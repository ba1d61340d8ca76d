#include "tests/testing/test_images.h"

#include <zlib.h>

#include <cstdio>
#include <cstring>
#include <memory>

namespace roomfix::testing {
namespace {

void PutBe32(std::vector<uint8_t>* out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<uint8_t>(v >> shift));
}

// One PNG chunk: length, type, data, CRC over type and data.
void Chunk(std::vector<uint8_t>* out, const char* type, const std::vector<uint8_t>& data) {
  PutBe32(out, static_cast<uint32_t>(data.size()));
  const size_t type_at = out->size();
  out->insert(out->end(), type, type + 4);
  out->insert(out->end(), data.begin(), data.end());
  const uLong crc = crc32(0L, out->data() + type_at, static_cast<uInt>(out->size() - type_at));
  PutBe32(out, static_cast<uint32_t>(crc));
}

std::vector<uint8_t> Ihdr(uint32_t width, uint32_t height, uint8_t colour_type) {
  std::vector<uint8_t> d;
  PutBe32(&d, width);
  PutBe32(&d, height);
  d.push_back(8);            // bit depth
  d.push_back(colour_type);  // 0 grey, 2 RGB
  d.push_back(0);            // deflate
  d.push_back(0);            // adaptive filtering
  d.push_back(0);            // no interlace
  return d;
}

const uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};

}  // namespace

std::vector<uint8_t> ForgedPngHeader(uint32_t width_px, uint32_t height_px) {
  std::vector<uint8_t> out(kSignature, kSignature + 8);
  Chunk(&out, "IHDR", Ihdr(width_px, height_px, 2));
  Chunk(&out, "IDAT", {});
  Chunk(&out, "IEND", {});
  return out;
}

bool WriteOneColourPng(const std::string& path, int width_px, int height_px, uint8_t grey) {
  std::vector<uint8_t> head(kSignature, kSignature + 8);
  Chunk(&head, "IHDR", Ihdr(static_cast<uint32_t>(width_px), static_cast<uint32_t>(height_px), 0));
  z_stream z{};
  // Run-length matching: as small as deflate gets on one colour, and fast.
  if (deflateInit2(&z, 6, Z_DEFLATED, 15, 8, Z_RLE) != Z_OK) return false;
  std::vector<uint8_t> row(static_cast<size_t>(width_px) + 1, grey);
  row[0] = 0;  // filter: none
  std::vector<uint8_t> compressed;
  std::vector<uint8_t> buffer(1 << 16);
  for (int y = 0; y <= height_px; ++y) {
    const bool last = y == height_px;
    z.next_in = last ? nullptr : row.data();
    z.avail_in = last ? 0 : static_cast<uInt>(row.size());
    int rc = Z_OK;
    do {
      z.next_out = buffer.data();
      z.avail_out = static_cast<uInt>(buffer.size());
      rc = deflate(&z, last ? Z_FINISH : Z_NO_FLUSH);
      compressed.insert(compressed.end(), buffer.data(),
                        buffer.data() + (buffer.size() - z.avail_out));
    } while (z.avail_out == 0 || (last && rc != Z_STREAM_END));
  }
  deflateEnd(&z);
  Chunk(&head, "IDAT", compressed);
  Chunk(&head, "IEND", {});
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "wb"), std::fclose);
  if (!f) return false;
  return std::fwrite(head.data(), 1, head.size(), f.get()) == head.size();
}

}  // namespace roomfix::testing
