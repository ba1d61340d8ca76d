// roomfix_bench radio: how fast the bridge decodes the coordinator's bytes,
// how soon a completed firing is published, and how the reference's way of
// grouping reports (by arrival, with no firing number) fares on the same
// faulty radio as roomfix's (by beacon and firing number).
#include <fmt/format.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "bench/commands.h"
#include "core/analysis/track_error.h"
#include "core/radio/wall_payload.h"
#include "core/radio/xbee_frame.h"
#include "msgio/channels.h"
#include "msgio/install_paths.h"
#include "msgio/process.h"
#include "roomfix/range_set_t.hpp"
#include "sim/pseudo_terminal.h"
#include "sim/wall_devices.h"
#include "zigbee_bridge/bridge_node.h"
#include "zigbee_bridge/serial_link.h"

namespace roomfix {
namespace {

using json = nlohmann::ordered_json;
using analysis::Percentile;

struct BenchRadioOptions {
  std::string site = DataFile("config/sites/demo_room.yaml");
  double stream_mb = 32.0;
  int repeats = 5;
  int latency_firings = 400;
  double compare_seconds = 600.0;
  bool json = false;
};

double Seconds(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

// Counts frames; the cheapest possible consumer, so the figure is the
// decoder's own.
class CountingSink : public radio::FrameSink {
 public:
  void OnFrame(const uint8_t*, size_t, uint64_t) override { ++frames; }
  void OnFrameError(const radio::FrameErrorInfo&) override { ++errors; }
  int64_t frames = 0;
  int64_t errors = 0;
};

// A coordinator's stream of roomfix frames (announcements and reports in
// 0x90 frames, the payload bytes varied so that mode 2 escapes some).
std::vector<uint8_t> MakeStream(const Site& site, radio::ApiMode mode, size_t bytes_wanted,
                                int64_t* frames) {
  std::vector<uint8_t> stream;
  stream.reserve(bytes_wanted + 64);
  uint16_t seq = 0;
  *frames = 0;
  while (stream.size() < bytes_wanted) {
    radio::ReceivePacket p;
    p.has_address64 = true;
    p.has_address16 = true;
    radio::WallMessage m;
    m.beacon_id = 1;
    m.firing_seq = seq;
    if (*frames % 5 == 0) {
      m.type = radio::PayloadType::kFiring;
      p.address64 = site.beacons[0].address;
    } else {
      m.type = radio::PayloadType::kRangeReport;
      m.time_of_flight_ns = 7'000'000u + static_cast<uint32_t>(*frames) * 7919u % 3'000'000u;
      m.temperature_centi_c = 2100;
      p.address64 =
          site.receivers[static_cast<size_t>(*frames % 5 - 1) % site.receivers.size()].address;
    }
    p.address16 = static_cast<uint16_t>(p.address64);
    p.payload = radio::EncodeWallMessage(m);
    const std::vector<uint8_t> data = radio::EncodeReceivePacket(p);
    radio::AppendFrame(data.data(), data.size(), mode, &stream);
    if (++*frames % 5 == 0) ++seq;
  }
  return stream;
}

json DecodeThroughput(const Site& site, const BenchRadioOptions& options) {
  json out = json::object();
  for (radio::ApiMode mode : {radio::ApiMode::kUnescaped, radio::ApiMode::kEscaped}) {
    int64_t frames = 0;
    const std::vector<uint8_t> stream =
        MakeStream(site, mode, static_cast<size_t>(options.stream_mb * 1e6), &frames);
    std::vector<double> mbps;
    std::vector<double> node_fps;
    for (int r = 0; r < options.repeats; ++r) {
      radio::FrameDecoderOptions decoder_options;
      decoder_options.mode = mode;
      radio::FrameDecoder decoder(decoder_options);
      CountingSink sink;
      const auto t0 = std::chrono::steady_clock::now();
      // 4 KiB reads, as a serial port delivers them at best.
      for (size_t i = 0; i < stream.size(); i += 4096) {
        decoder.Feed(stream.data() + i, std::min<size_t>(4096, stream.size() - i), &sink);
      }
      const double s = Seconds(std::chrono::steady_clock::now() - t0);
      if (sink.frames != frames || sink.errors != 0) {
        std::cerr << "roomfix_bench radio: decoder lost frames (" << sink.frames << " of " << frames
                  << ", " << sink.errors << " errors)\n";
        return nullptr;
      }
      mbps.push_back(stream.size() / s / 1e6);
    }
    // The whole bridge on the same stream: decode, parse, assemble, encode
    // and publish range sets (to an in-process bus with one subscriber).
    for (int r = 0; r < std::max(1, options.repeats / 2); ++r) {
      LoopbackBus bus;
      int64_t sets = 0;
      bus.Subscribe<range_set_t>(kRangesChannel,
                                 [&](const range_set_t&, const MessageInfo&) { ++sets; });
      BridgeNodeOptions node_options;
      node_options.api_mode = mode;
      BridgeNode node(site, &bus, node_options, 0);
      const auto t0 = std::chrono::steady_clock::now();
      int64_t now = 1;
      for (size_t i = 0; i < stream.size(); i += 4096) {
        node.OnBytes(stream.data() + i, std::min<size_t>(4096, stream.size() - i), now);
        now += 1000;
      }
      const double s = Seconds(std::chrono::steady_clock::now() - t0);
      node_fps.push_back(frames / s);
      if (sets < frames / 5 - 1) {
        std::cerr << "roomfix_bench radio: the node published " << sets << " sets of " << frames / 5
                  << "\n";
        return nullptr;
      }
    }
    json m;
    m["stream_mb"] = stream.size() / 1e6;
    m["frames"] = frames;
    m["decode_mb_per_s_median"] = Percentile(mbps, 0.5);
    m["decode_mb_per_s_best"] = *std::max_element(mbps.begin(), mbps.end());
    m["bridge_frames_per_s_median"] = Percentile(node_fps, 0.5);
    out[mode == radio::ApiMode::kEscaped ? "api_mode_2" : "api_mode_1"] = m;
  }
  return out;
}

// Latency through a real pseudo-terminal: a writer thread sends a firing's
// announcement and first reports, then the last report; the bridge loop
// (SerialLink + BridgeNode, as in zigbee_bridge) publishes the set. Measured:
// from the write of the last report's bytes (and from the read that returned
// them) to the publish call.
json PublishLatency(const Site& site, const BenchRadioOptions& options, std::string* error) {
  char dir_template[] = "/tmp/roomfix_bench_radio_XXXXXX";
  if (::mkdtemp(dir_template) == nullptr) {
    *error = "cannot make a temporary folder";
    return nullptr;
  }
  const std::string link = std::string(dir_template) + "/radio";
  auto pty = PseudoTerminal::Open(link, error);
  if (pty == nullptr) return nullptr;

  struct Firing {
    std::vector<uint8_t> head;  // announcement and all reports but the last
    std::vector<uint8_t> last;  // the last report
  };
  std::vector<Firing> firings;
  for (int k = 0; k < options.latency_firings; ++k) {
    Firing f;
    auto frame = [&](uint64_t address, const radio::WallMessage& m, std::vector<uint8_t>* out) {
      radio::ReceivePacket p;
      p.has_address64 = true;
      p.address64 = address;
      p.has_address16 = true;
      p.payload = radio::EncodeWallMessage(m);
      const std::vector<uint8_t> data = radio::EncodeReceivePacket(p);
      radio::AppendFrame(data.data(), data.size(), radio::ApiMode::kEscaped, out);
    };
    radio::WallMessage m;
    m.type = radio::PayloadType::kFiring;
    m.beacon_id = 1;
    m.firing_seq = static_cast<uint16_t>(k);
    frame(site.beacons[0].address, m, &f.head);
    for (size_t r = 0; r < site.receivers.size(); ++r) {
      m.type = radio::PayloadType::kRangeReport;
      m.time_of_flight_ns = 8'000'000;
      frame(site.receivers[r].address, m, r + 1 == site.receivers.size() ? &f.last : &f.head);
    }
    firings.push_back(std::move(f));
  }

  std::vector<int64_t> write_utime(firings.size(), 0);
  std::vector<int64_t> read_utime(firings.size(), 0);
  std::vector<int64_t> publish_utime(firings.size(), 0);
  std::atomic<int> published{0};
  std::atomic<bool> ready{false};
  std::atomic<bool> stop{false};

  std::thread bridge_thread([&] {
    LoopbackBus bus;
    SerialLink link_port(SerialLinkOptions{link, 115200, 0.01, 0.1});
    BridgeNode node(site, &bus, {}, NowUtime());
    int64_t last_read = 0;
    bus.Subscribe<range_set_t>(kRangesChannel, [&](const range_set_t& s, const MessageInfo&) {
      const auto k = static_cast<size_t>(s.firing_seq);
      if (k < publish_utime.size()) {
        publish_utime[k] = NowUtime();
        read_utime[k] = last_read;
      }
      ++published;
    });
    std::vector<uint8_t> buffer(4096);
    while (!stop) {
      if (link_port.state() != SerialLink::State::kOpen && link_port.MaybeOpen(NowUtime())) {
        node.OnLinkUp(link, NowUtime());
        ready = true;
      }
      pollfd fd{link_port.fd(), POLLIN, 0};
      ::poll(&fd, 1, 2);
      while (link_port.state() == SerialLink::State::kOpen) {
        last_read = NowUtime();
        const int n = link_port.Read(buffer.data(), buffer.size(), last_read);
        if (n <= 0) break;
        node.OnBytes(buffer.data(), static_cast<size_t>(n), last_read);
      }
      node.Tick(NowUtime());
    }
  });
  while (!ready) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  bool wrote_all = true;
  for (size_t k = 0; k < firings.size() && wrote_all; ++k) {
    wrote_all = pty->Write(firings[k].head.data(), firings[k].head.size(), error);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    write_utime[k] = NowUtime();
    wrote_all = wrote_all && pty->Write(firings[k].last.data(), firings[k].last.size(), error);
    std::this_thread::sleep_for(std::chrono::milliseconds(3));
  }
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (published < static_cast<int>(firings.size()) &&
         std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  stop = true;
  bridge_thread.join();
  pty.reset();
  ::rmdir(dir_template);
  if (!wrote_all) return nullptr;

  std::vector<double> from_write_ms;
  std::vector<double> from_read_ms;
  for (size_t k = 0; k < firings.size(); ++k) {
    if (publish_utime[k] == 0) continue;
    from_write_ms.push_back((publish_utime[k] - write_utime[k]) * 1e-3);
    from_read_ms.push_back((publish_utime[k] - read_utime[k]) * 1e-3);
  }
  if (from_write_ms.empty()) {
    *error = "no range set was published";
    return nullptr;
  }
  json out;
  out["firings"] = firings.size();
  out["published"] = from_write_ms.size();
  out["from_write_ms_median"] = Percentile(from_write_ms, 0.5);
  out["from_write_ms_p99"] = Percentile(from_write_ms, 0.99);
  out["from_write_ms_max"] = *std::max_element(from_write_ms.begin(), from_write_ms.end());
  out["from_read_ms_median"] = Percentile(from_read_ms, 0.5);
  out["from_read_ms_p99"] = Percentile(from_read_ms, 0.99);
  return out;
}

// The reference's association: no firing number, so every report belongs to
// the latest announcement, and any source address is taken. Scores the sets
// it forms the way the tests score the bridge's.
json CompareGrouping(const Site& site, const BenchRadioOptions& options) {
  WallDevicesOptions wall;
  wall.faults = RadioFaults::All();
  // Corruption and garbage hurt both methods alike (the frame checksum); the
  // comparison is about association.
  wall.faults.corrupt_byte_probability = 0.0;
  wall.faults.garbage_probability = 0.0;
  wall.seed = 3;
  VirtualWallDevices devices(site, wall);

  struct Group {
    int64_t seq = -1;
    int ranges = 0;
    bool mixed = false;
  };
  class ReferenceGrouping : public radio::FrameSink {
   public:
    explicit ReferenceGrouping(const Site& s) : site_(s) {}
    void OnFrame(const uint8_t* data, size_t size, uint64_t) override {
      radio::ReceivePacket p;
      if (radio::ParseReceivePacket(data, size, &p) != radio::PacketParse::kOk) return;
      radio::WallMessage m;
      if (radio::DecodeWallMessage(p.payload.data(), p.payload.size(), &m) !=
          radio::PayloadError::kOk) {
        return;
      }
      if (m.type == radio::PayloadType::kFiring) {
        groups.push_back({m.firing_seq, 0, false});
        return;
      }
      if (groups.empty() || m.time_of_flight_ns == 0) return;
      Group& g = groups.back();
      ++g.ranges;
      // The truth the reference could not see: the report's own firing, and
      // whether its sender belongs to this installation.
      if (m.firing_seq != static_cast<uint16_t>(g.seq) ||
          site_.FindReceiverByAddress(p.address64) == nullptr) {
        g.mixed = true;
      }
    }
    void OnFrameError(const radio::FrameErrorInfo&) override {}
    std::vector<Group> groups;

   private:
    const Site& site_;
  };

  ReferenceGrouping reference(site);
  radio::FrameDecoder reference_decoder;
  LoopbackBus bus;
  std::vector<range_set_t> sets;
  bus.Subscribe<range_set_t>(kRangesChannel,
                             [&](const range_set_t& s, const MessageInfo&) { sets.push_back(s); });
  BridgeNode node(site, &bus, {}, 0);
  node.OnLinkUp("simulated", 0);
  std::vector<VirtualWallDevices::Chunk> chunks;
  const auto end = static_cast<int64_t>(options.compare_seconds * 1e6);
  for (int64_t now = 0; now <= end; now += 1000) {
    chunks.clear();
    devices.AdvanceChunks(now, &chunks);
    for (const auto& c : chunks) {
      reference_decoder.Feed(c.bytes.data(), c.bytes.size(), &reference);
      node.OnBytes(c.bytes.data(), c.bytes.size(), c.utime);
    }
    node.Tick(now);
  }

  int reference_mixed = 0;
  int reference_with_ranges = 0;
  for (const Group& g : reference.groups) {
    if (g.ranges == 0) continue;
    ++reference_with_ranges;
    reference_mixed += g.mixed ? 1 : 0;
  }
  int roomfix_mixed = 0;
  int roomfix_with_ranges = 0;
  for (const range_set_t& s : sets) {
    if (s.ranges.empty()) continue;
    ++roomfix_with_ranges;
    const auto it = devices.ledger().find({s.beacon_id, s.firing_seq});
    if (it == devices.ledger().end()) {
      ++roomfix_mixed;
      continue;
    }
    for (const range_t& r : s.ranges) {
      bool own = false;
      for (const auto& rep : it->second.reports) {
        own |= rep.receiver_id == r.receiver_id && !rep.no_echo &&
               std::abs(rep.time_of_flight_ns - r.time_of_flight_us * 1e3) < 0.5;
      }
      if (!own) {
        ++roomfix_mixed;
        break;
      }
    }
  }
  json out;
  out["firings"] = devices.firings();
  out["faults"] = "all (buffering, reordering, duplicates, foreign modules, losses)";
  out["reference_sets"] = reference_with_ranges;
  out["reference_mixed_sets"] = reference_mixed;
  out["reference_mixed_share"] =
      reference_with_ranges > 0 ? static_cast<double>(reference_mixed) / reference_with_ranges : 0;
  out["roomfix_sets"] = roomfix_with_ranges;
  out["roomfix_mixed_sets"] = roomfix_mixed;
  out["roomfix_mixed_share"] =
      roomfix_with_ranges > 0 ? static_cast<double>(roomfix_mixed) / roomfix_with_ranges : 0;
  return out;
}

int RunRadioBench(const BenchRadioOptions& options) {
  // The bridge's own log lines (link up) would interleave with the figures.
  spdlog::set_level(spdlog::level::warn);
  Site site;
  std::string error;
  if (!LoadSite(options.site, &site, &error)) {
    std::cerr << "roomfix_bench radio: " << error << "\n";
    return 1;
  }
  if (site.beacons.empty() || site.simulation.robots.empty()) {
    std::cerr << "roomfix_bench radio: " << options.site
              << ": needs a beacon and a simulated robot carrying it\n";
    return 1;
  }
  json result;
  result["decode"] = DecodeThroughput(site, options);
  if (result["decode"].is_null()) return 1;
  result["latency"] = PublishLatency(site, options, &error);
  if (result["latency"].is_null()) {
    std::cerr << "roomfix_bench radio: latency: " << error << "\n";
    return 1;
  }
  result["grouping"] = CompareGrouping(site, options);
  if (options.json) {
    std::cout << result.dump() << "\n";
    return 0;
  }
  const json& d = result["decode"];
  fmt::print("XBee API decoding ({:.0f} MB of 0x90 frames, 4 KiB reads, median of {})\n",
             d["api_mode_2"]["stream_mb"].get<double>(), options.repeats);
  for (const char* mode : {"api_mode_1", "api_mode_2"}) {
    fmt::print(
        "  {}: {:8.1f} MB/s decode (best {:.1f}), {:10.0f} frames/s through the whole bridge\n",
        mode, d[mode]["decode_mb_per_s_median"].get<double>(),
        d[mode]["decode_mb_per_s_best"].get<double>(),
        d[mode]["bridge_frames_per_s_median"].get<double>());
  }
  const json& l = result["latency"];
  fmt::print(
      "Last report to RANGES, through a pseudo-terminal ({} firings)\n"
      "  from the write:  median {:.3f} ms, p99 {:.3f} ms, max {:.3f} ms\n"
      "  from the read:   median {:.3f} ms, p99 {:.3f} ms\n",
      l["published"].get<int>(), l["from_write_ms_median"].get<double>(),
      l["from_write_ms_p99"].get<double>(), l["from_write_ms_max"].get<double>(),
      l["from_read_ms_median"].get<double>(), l["from_read_ms_p99"].get<double>());
  const json& g = result["grouping"];
  fmt::print(
      "Grouping reports into firings on a faulty radio ({} firings, every fault on)\n"
      "  reference (latest announcement, any address): {:5} of {:5} sets mixed ({:.1f}%)\n"
      "  roomfix (beacon + firing number, allowlist):  {:5} of {:5} sets mixed ({:.1f}%)\n",
      static_cast<long long>(g["firings"].get<int64_t>()), g["reference_mixed_sets"].get<int>(),
      g["reference_sets"].get<int>(), 100.0 * g["reference_mixed_share"].get<double>(),
      g["roomfix_mixed_sets"].get<int>(), g["roomfix_sets"].get<int>(),
      100.0 * g["roomfix_mixed_share"].get<double>());
  return 0;
}

}  // namespace

void AddBenchRadioCommand(CLI::App* bench, int* exit_code) {
  auto options = std::make_shared<BenchRadioOptions>();
  auto* radio = bench->add_subcommand(
      "radio",
      "zigbee_bridge: decoding throughput, latency from the last report to RANGES through a "
      "pseudo-terminal, and the reference's report grouping against roomfix's on a faulty radio");
  radio->add_option("--site", options->site, "Site file")->capture_default_str();
  radio->add_option("--stream-mb", options->stream_mb, "Size of the decoded stream, MB")
      ->capture_default_str();
  radio->add_option("--repeats", options->repeats, "Decoding runs per API mode")
      ->capture_default_str();
  radio
      ->add_option("--latency-firings", options->latency_firings,
                   "Firings sent through the pseudo-terminal")
      ->capture_default_str();
  radio
      ->add_option("--compare-seconds", options->compare_seconds,
                   "Simulated time of the grouping comparison, s")
      ->capture_default_str();
  radio->add_flag("--json", options->json, "Print one JSON object instead of tables");
  radio->callback([options, exit_code] { *exit_code = RunRadioBench(*options); });
}

}  // namespace roomfix
