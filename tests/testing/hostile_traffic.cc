#include "tests/testing/hostile_traffic.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>

#include "roomfix/detector_view_request_t.hpp"
#include "roomfix/detector_view_t.hpp"
#include "roomfix/image_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/process_status_t.hpp"

namespace roomfix::hostile {
namespace {

constexpr uint32_t kMagicShort = 0x4c433032;  // "LC02"
constexpr uint32_t kMagicLong = 0x4c433033;   // "LC03"
// liblcm sends a message whole up to this many bytes (channel and payload),
// fragments it above.
constexpr size_t kShortMessageMaxBytes = 1400;
constexpr size_t kFragmentBytes = 1400;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

void PutU32(Bytes* out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<uint8_t>(v >> shift));
}
void PutU16(Bytes* out, uint16_t v) {
  out->push_back(static_cast<uint8_t>(v >> 8));
  out->push_back(static_cast<uint8_t>(v));
}

// Overwrites the big-endian int32 at offset, after checking that it holds
// what the layout says it does: an offset that drifted with a type change
// fails loudly here instead of patching the wrong field.
Bytes PatchInt32(Bytes payload, size_t offset, int32_t expected, int32_t value) {
  if (offset + 4 > payload.size()) throw std::logic_error("hostile: patch offset past the payload");
  uint32_t old = 0;
  for (size_t i = 0; i < 4; ++i) old = (old << 8) | payload[offset + i];
  if (static_cast<int32_t>(old) != expected) {
    throw std::logic_error("hostile: the field at offset " + std::to_string(offset) + " holds " +
                           std::to_string(static_cast<int32_t>(old)) + ", not " +
                           std::to_string(expected) + "; the type's layout changed");
  }
  const auto v = static_cast<uint32_t>(value);
  for (size_t i = 0; i < 4; ++i) payload[offset + i] = static_cast<uint8_t>(v >> (24 - 8 * i));
  return payload;
}

}  // namespace

Bytes ShortDatagram(uint32_t seqno, const std::string& channel, const Bytes& payload) {
  Bytes out;
  PutU32(&out, kMagicShort);
  PutU32(&out, seqno);
  out.insert(out.end(), channel.begin(), channel.end());
  out.push_back(0);
  out.insert(out.end(), payload.begin(), payload.end());
  return out;
}

Bytes FragmentDatagram(uint32_t seqno, uint32_t total_size, uint32_t offset, uint16_t fragment_no,
                       uint16_t fragment_count, const std::string& channel, const Bytes& data) {
  Bytes out;
  PutU32(&out, kMagicLong);
  PutU32(&out, seqno);
  PutU32(&out, total_size);
  PutU32(&out, offset);
  PutU16(&out, fragment_no);
  PutU16(&out, fragment_count);
  if (fragment_no == 0) {
    out.insert(out.end(), channel.begin(), channel.end());
    out.push_back(0);
  }
  out.insert(out.end(), data.begin(), data.end());
  return out;
}

Sender::Sender(const std::string& lcm_url) {
  // udpm://GROUP:PORT?key=value&...; only ttl matters to a sender.
  const std::string prefix = "udpm://";
  if (lcm_url.rfind(prefix, 0) != 0) {
    error_ = lcm_url + ": not a udpm:// URL";
    return;
  }
  std::string rest = lcm_url.substr(prefix.size());
  std::string query;
  if (const size_t q = rest.find('?'); q != std::string::npos) {
    query = rest.substr(q + 1);
    rest.resize(q);
  }
  const size_t colon = rest.find(':');
  const std::string group = rest.substr(0, colon);
  const int port = colon == std::string::npos ? 7667 : std::atoi(rest.c_str() + colon + 1);
  int ttl = 0;
  if (const size_t t = query.find("ttl="); t != std::string::npos) {
    ttl = std::atoi(query.c_str() + t + 4);
  }
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  if (inet_pton(AF_INET, group.c_str(), &addr.sin_addr) != 1) {
    error_ = lcm_url + ": bad group address";
    return;
  }
  static_assert(sizeof(addr) <= sizeof(addr_));
  std::memcpy(addr_, &addr, sizeof(addr));
  fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
  if (fd_ < 0) {
    error_ = std::string("socket: ") + std::strerror(errno);
    return;
  }
  const unsigned char ttl_byte = static_cast<unsigned char>(ttl);
  const unsigned char loop = 1;
  // A big send buffer, so a burst is limited by the receivers, not by us.
  const int sndbuf = 4 << 20;
  if (::setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_TTL, &ttl_byte, sizeof(ttl_byte)) != 0 ||
      ::setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof(loop)) != 0 ||
      ::setsockopt(fd_, SOL_SOCKET, SO_SNDBUF, &sndbuf, sizeof(sndbuf)) != 0) {
    error_ = std::string("setsockopt: ") + std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
  }
}

Sender::~Sender() {
  if (fd_ >= 0) ::close(fd_);
}

bool Sender::Send(const Bytes& datagram) {
  if (fd_ < 0) return false;
  // Loopback multicast only fails transiently when the send buffer is full;
  // retrying keeps a burst whole instead of silently thinning it.
  for (int attempt = 0; attempt < 1000; ++attempt) {
    const ssize_t n = ::sendto(fd_, datagram.data(), datagram.size(), 0,
                               reinterpret_cast<const sockaddr*>(addr_), sizeof(sockaddr_in));
    if (n == static_cast<ssize_t>(datagram.size())) return true;
    if (errno != ENOBUFS && errno != EAGAIN) break;
    ::usleep(100);
  }
  error_ = std::string("sendto: ") + std::strerror(errno);
  return false;
}

bool Sender::SendAll(const std::vector<Bytes>& datagrams) {
  bool ok = true;
  for (const Bytes& d : datagrams) ok = Send(d) && ok;
  return ok;
}

bool Sender::Publish(const std::string& channel, const Bytes& payload) {
  const uint32_t seqno = NextSeqno();
  if (channel.size() + 1 + payload.size() <= kShortMessageMaxBytes) {
    return Send(ShortDatagram(seqno, channel, payload));
  }
  const size_t first = kFragmentBytes - channel.size() - 1;
  const size_t count = 1 + (payload.size() - first + kFragmentBytes - 1) / kFragmentBytes;
  bool ok = true;
  size_t offset = 0;
  for (size_t k = 0; k < count; ++k) {
    const size_t n = std::min(k == 0 ? first : kFragmentBytes, payload.size() - offset);
    const Bytes data(payload.begin() + static_cast<std::ptrdiff_t>(offset),
                     payload.begin() + static_cast<std::ptrdiff_t>(offset + n));
    ok = Send(FragmentDatagram(seqno, static_cast<uint32_t>(payload.size()),
                               static_cast<uint32_t>(offset), static_cast<uint16_t>(k),
                               static_cast<uint16_t>(count), channel, data)) &&
         ok;
    offset += n;
  }
  return ok;
}

range_set_t GoodRanges(int64_t firing_seq, int64_t utime) {
  constexpr double kBeaconZ_m = 1.3;
  constexpr double kSpeedOfSound_mps = 343.8;
  const double corners[4][3] = {{0, 0, 2.5}, {4, 0, 2.5}, {4, 3, 2.5}, {0, 3, 2.5}};
  range_set_t s{};
  s.utime = utime;
  s.beacon_id = 1;
  s.firing_seq = firing_seq;
  s.speed_of_sound_mps = kSpeedOfSound_mps;
  s.temperature_c = 21.0;
  s.num_expected = 4;
  for (int i = 0; i < 4; ++i) {
    range_t r{};
    r.receiver_id = i + 1;
    for (int k = 0; k < 3; ++k) r.receiver_position_m[k] = corners[i][k];
    r.range_m =
        std::hypot(corners[i][0] - kGoodX_m, corners[i][1] - kGoodY_m, corners[i][2] - kBeaconZ_m);
    r.time_of_flight_us = r.range_m / kSpeedOfSound_mps * 1e6;
    // Saturating: the absurd-time class sends utimes at the int64 limits.
    r.arrival_utime = utime > std::numeric_limits<int64_t>::max() - 20'000 ? utime : utime + 20'000;
    s.ranges.push_back(r);
  }
  s.num_ranges = static_cast<int32_t>(s.ranges.size());
  return s;
}

pose2d_t GoodPose(int8_t source, int64_t measurement_seq, int64_t utime) {
  pose2d_t p{};
  p.utime = utime;
  p.source = source;
  p.camera_id = source == pose2d_t::SOURCE_CAMERA ? 0 : -1;  // demo_room's camera; kNoCameraId
  p.robot_id = 1;
  p.measurement_seq = measurement_seq;
  p.x_m = kGoodX_m;
  p.y_m = kGoodY_m;
  p.z_m = source == pose2d_t::SOURCE_CAMERA ? 0.2 : 1.3;
  p.heading_rad = source == pose2d_t::SOURCE_CAMERA ? 0.5 : kNaN;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) p.covariance[r][c] = r == c ? 1e-4 : 0.0;
  }
  if (source != pose2d_t::SOURCE_CAMERA) {
    p.covariance[2][2] = p.covariance[0][2] = p.covariance[2][0] = kNaN;
    p.covariance[1][2] = p.covariance[2][1] = kNaN;
  }
  p.residual_m = 0.005;
  p.num_measurements = 4;
  p.status = pose2d_t::STATUS_OK;
  p.latency_us = 5'000;
  return p;
}

std::vector<Bytes> ConflictingTotalFragments(uint32_t seqno, const std::string& channel) {
  constexpr uint32_t kFirstTotal = 1'500;
  constexpr uint32_t kSecondTotal = 65'000;
  constexpr uint32_t kSecondOffset = 60'000;
  const Bytes first_data(1'000, 0xAB);
  const Bytes second_data(1'000, 0xCD);
  return {FragmentDatagram(seqno, kFirstTotal, 0, 0, 2, channel, first_data),
          FragmentDatagram(seqno, kSecondTotal, kSecondOffset, 1, 2, channel, second_data)};
}

Bytes HugeFirstFragment(uint32_t seqno, const std::string& channel) {
  const size_t data_bytes = kFragmentBytes - channel.size() - 1;
  const auto count = static_cast<uint16_t>((kHugeMessageBytes + data_bytes - 1) / data_bytes);
  return FragmentDatagram(seqno, kHugeMessageBytes, 0, 0, count, channel, Bytes(data_bytes, 0x5A));
}

Bytes StatusWithNegativeStringLength() {
  process_status_t s{};
  s.utime = 1;
  s.process = "hostile";
  s.host = "attacker";
  // fingerprint (8) + utime (8): the length of `process`, NUL included.
  return PatchInt32(Encode(s), 16, static_cast<int32_t>(s.process.size() + 1),
                    std::numeric_limits<int32_t>::min());
}

Bytes MarkerPixelsWithNegativeStringLength() {
  marker_pixels_t m{};
  m.utime = 1;
  marker_t marker{};
  marker.colour_class = "orange";
  marker.robot_id = 1;
  m.markers.push_back(marker);
  m.num_markers = 1;
  // fingerprint 8, utime 8, camera_id 4, frame_seq 8, width 4, height 4,
  // search_mode 1, processing_time 4, num_markers 4: markers[0].colour_class.
  return PatchInt32(Encode(m), 45, static_cast<int32_t>(marker.colour_class.size() + 1),
                    std::numeric_limits<int32_t>::min());
}

Bytes CameraPreviewWithNegativeStringLength() {
  image_t m{};
  m.utime = 1;
  m.width_px = m.height_px = 2;
  m.source_width_px = m.source_height_px = 2;
  m.format = "png";
  m.num_bytes = 4;
  m.data.assign(4, 0);
  // fingerprint 8, utime 8, camera_id 4, frame_seq 8, four int32 sizes: format.
  return PatchInt32(Encode(m), 44, static_cast<int32_t>(m.format.size() + 1),
                    std::numeric_limits<int32_t>::min());
}

Bytes DetectorViewWithNegativeStringLength() {
  detector_view_t m{};
  m.utime = 1;
  m.width_px = m.height_px = m.source_width_px = m.source_height_px = 2;
  m.scale = 1;
  m.format = "png";
  m.num_bytes = 4;
  m.data.assign(4, 0);
  // fingerprint 8, utime 8, camera_id 4, frame_seq 8, nine int32 (sizes,
  // region, scale) 36: format.
  return PatchInt32(Encode(m), 64, static_cast<int32_t>(m.format.size() + 1),
                    std::numeric_limits<int32_t>::min());
}

std::vector<Bytes> HostileDetectorViewRequests(int64_t utime) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  constexpr int32_t kMin = std::numeric_limits<int32_t>::min();
  constexpr int32_t kMax = std::numeric_limits<int32_t>::max();
  auto request = [&](double rate_hz, double duration_s, int32_t u, int32_t v, int32_t w, int32_t h,
                     int32_t camera_id) {
    detector_view_request_t r{};
    r.utime = utime;
    r.camera_id = camera_id;
    r.region_u_px = u;
    r.region_v_px = v;
    r.region_width_px = w;
    r.region_height_px = h;
    r.rate_hz = rate_hz;
    r.duration_s = duration_s;
    return Encode(r);
  };
  return {request(nan, 10, 0, 0, 0, 0, -1),
          request(inf, 10, 0, 0, 0, 0, -1),
          request(1, nan, 0, 0, 0, 0, -1),
          request(1, inf, 0, 0, 0, 0, -1),
          request(1, 3.2e7, 0, 0, 0, 0, -1),
          request(-1, 10, 0, 0, 0, 0, -1),
          request(0, 10, 0, 0, 0, 0, -1),
          request(1, 10, 5000, 5000, 64, 64, -1),
          request(1, 10, kMin, kMin, kMax, kMax, -1),
          request(1, 10, 0, 0, kMax, 64, -1),
          request(1, 10, 0, 0, 0, 0, kMin)};
}

Bytes RangesClaimingCount(int32_t count) {
  range_set_t s = GoodRanges(1, 1);
  s.ranges.clear();
  s.num_ranges = 0;
  // fingerprint 8, utime 8, beacon_id 4, firing_seq 8, two doubles 16,
  // num_expected 4: num_ranges, the last field when there are no ranges.
  return PatchInt32(Encode(s), 48, 0, count);
}

range_set_t InconsistentRanges(int n, int64_t firing_seq, int64_t utime, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> x(-2.0, 6.0), y(-2.0, 5.0), z(0.0, 3.3), range(0.1, 8.0);
  range_set_t s = GoodRanges(firing_seq, utime);
  s.ranges.clear();
  s.num_expected = n;
  for (int i = 0; i < n; ++i) {
    range_t r{};
    r.receiver_id = i + 1;
    r.receiver_position_m[0] = x(rng);
    r.receiver_position_m[1] = y(rng);
    r.receiver_position_m[2] = z(rng);
    r.range_m = range(rng);
    r.time_of_flight_us = r.range_m / s.speed_of_sound_mps * 1e6;
    // Saturating: the absurd-time class sends utimes at the int64 limits.
    r.arrival_utime = utime > std::numeric_limits<int64_t>::max() - 20'000 ? utime : utime + 20'000;
    s.ranges.push_back(r);
  }
  s.num_ranges = n;
  return s;
}

Bytes EmptyChannelDatagram(uint32_t seqno) {
  return ShortDatagram(seqno, "", Encode(GoodPose(pose2d_t::SOURCE_CAMERA, 0, 1)));
}

pose2d_t PoseForNewRobot(int8_t source, int32_t robot_id, int64_t utime) {
  pose2d_t p = GoodPose(source, robot_id, utime);
  p.robot_id = robot_id;
  return p;
}

range_set_t NonFiniteRanges(int64_t firing_seq, int64_t utime) {
  range_set_t s = GoodRanges(firing_seq, utime);
  s.ranges[0].range_m = kNaN;
  s.ranges[1].receiver_position_m[0] = kInf;
  s.ranges[2].time_of_flight_us = -kInf;
  s.speed_of_sound_mps = kNaN;
  return s;
}

std::vector<pose2d_t> NonFinitePoses(int8_t source, int64_t utime) {
  std::vector<pose2d_t> out;
  pose2d_t nan_x = GoodPose(source, 1, utime);
  nan_x.x_m = kNaN;
  out.push_back(nan_x);
  pose2d_t inf_y = GoodPose(source, 2, utime);
  inf_y.y_m = kInf;
  out.push_back(inf_y);
  pose2d_t bad_cov = GoodPose(source, 3, utime);
  bad_cov.covariance[0][0] = kInf;
  bad_cov.covariance[1][1] = kNaN;
  out.push_back(bad_cov);
  return out;
}

std::vector<int64_t> AbsurdUtimes(int64_t now_utime) {
  return {now_utime + kFarFutureOffsetUs, std::numeric_limits<int64_t>::max(), -kFarFutureOffsetUs,
          std::numeric_limits<int64_t>::min()};
}

}  // namespace roomfix::hostile
