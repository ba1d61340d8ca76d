#ifndef ROOMFIX_TESTS_TESTING_TEST_IMAGES_H_
#define ROOMFIX_TESTS_TESTING_TEST_IMAGES_H_

#include <cstdint>
#include <string>
#include <vector>

namespace roomfix::testing {

// A valid 8-bit greyscale PNG of one colour, width x height, written row by
// row through zlib so that a 20000 x 20000 image (400 MB of pixels, about
// 390 KB of file) is made in a few MB of memory. What an attacker would put
// in an image folder: small on disk, gigabytes once decoded.
bool WriteOneColourPng(const std::string& path, int width_px, int height_px, uint8_t grey = 128);

// The 57-byte PNG of the audit: signature, an IHDR claiming width x height
// (8-bit RGB), an empty IDAT and IEND, every CRC right. Any decoder that
// trusts the header allocates width * height * 3 bytes.
std::vector<uint8_t> ForgedPngHeader(uint32_t width_px, uint32_t height_px);

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_TEST_IMAGES_H_
