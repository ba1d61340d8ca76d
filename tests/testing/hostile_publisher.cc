// roomfix_hostile: sends one class of hostile or broken LCM traffic
// (tests/testing/hostile_traffic.h) to the bus, to reproduce by hand what
// tests/netns/hostile_traffic_test.cc does to the real processes. Run it only
// inside a private network namespace (scripts/netns_run) or on an isolated
// lab network: it is an attack on every process listening. Flags here; the
// classes and the send loop are in hostile_classes.h.
#include <CLI/CLI.hpp>
#include <iostream>

#include "tests/testing/hostile_classes.h"

namespace {

int Fail(const std::string& error) {
  std::cerr << "roomfix_hostile: " << error << "\n";
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  roomfix::hostile::PublisherOptions options;
  CLI::App app{"roomfix_hostile: sends one class of hostile LCM traffic (issue #15) to the bus"};
  app.add_option("--lcm-url", options.lcm_url, "LCM URL (udpm:// only)")->capture_default_str();
  app.add_option("--count", options.count, "How many times to send the class")
      ->capture_default_str();
  app.add_option("--rate", options.rate_hz, "Sends per second (0: as fast as possible)");
  std::string help = "Class to send:";
  for (const auto& [name, traffic] : roomfix::hostile::TrafficClasses()) {
    help += "\n  " + name + ": " + traffic.description;
  }
  app.add_option("CLASS", options.class_name, help)->required();
  CLI11_PARSE(app, argc, argv);
  std::string error;
  if (!options.IsValid(&error)) return Fail(error);
  return roomfix::hostile::SendTraffic(options, &error) == 0 ? 0 : Fail(error);
}
