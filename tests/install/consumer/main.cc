// Encodes a pose with the installed headers and decodes it back; binds a
// message constant to a reference (an odr-use, which links only because
// roomfix::lcmtypes supplies the definitions lcm-gen 1.3.1 leaves out).
#include <cstdio>
#include <vector>

#include "roomfix/pose2d_t.hpp"

namespace {
const int8_t& FusedSource() { return roomfix::pose2d_t::SOURCE_FUSED; }
}  // namespace

int main() {
  roomfix::pose2d_t pose{};
  pose.utime = 1700000000000000;
  pose.source = FusedSource();
  pose.x_m = 1.25;
  pose.y_m = -0.5;
  std::vector<char> bytes(static_cast<size_t>(pose.getEncodedSize()));
  if (pose.encode(bytes.data(), 0, static_cast<int>(bytes.size())) != pose.getEncodedSize()) {
    std::fprintf(stderr, "encode failed\n");
    return 1;
  }
  roomfix::pose2d_t back{};
  if (back.decode(bytes.data(), 0, static_cast<int>(bytes.size())) != pose.getEncodedSize()) {
    std::fprintf(stderr, "decode failed\n");
    return 1;
  }
  std::printf("pose2d_t %d bytes: source %d x_m %.2f y_m %.2f\n", pose.getEncodedSize(),
              back.source, back.x_m, back.y_m);
  return back.source == 3 && back.x_m == 1.25 && back.y_m == -0.5 ? 0 : 1;
}
