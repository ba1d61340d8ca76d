#ifndef ROOMFIX_TESTS_TESTING_HOSTILE_CLASSES_H_
#define ROOMFIX_TESTS_TESTING_HOSTILE_CLASSES_H_

// roomfix_hostile's part besides its flags: the classes of hostile traffic
// (hostile_traffic.h) it sends by name, and the paced send loop.

#include <functional>
#include <map>
#include <string>

#include "msgio/process.h"
#include "tests/testing/hostile_traffic.h"

namespace roomfix::hostile {

// One class of hostile traffic: what it is (the --help line) and how to send
// its k-th instance (k = 0, 1, ...; classes that vary, vary with k).
struct TrafficClass {
  std::string description;
  std::function<bool(Sender& sender, int k)> send;
};

// Every class by name, in the order --help lists them.
const std::map<std::string, TrafficClass>& TrafficClasses();

// What roomfix_hostile's flags choose.
struct PublisherOptions {
  std::string lcm_url = kDefaultLcmUrl;
  std::string class_name;
  int count = 1;
  // Sends per second (<= 0: as fast as possible).
  double rate_hz = 0.0;

  // False with "unknown class 'NAME'" when class_name is not in
  // TrafficClasses().
  bool IsValid(std::string* error) const;
};

// Sends the class `count` times, the k-th at k / rate_hz after the start.
// 0, or 1 with the sender's reason (a URL that is not udpm://, a failed
// sendto) at the first failure.
int SendTraffic(const PublisherOptions& options, std::string* error);

}  // namespace roomfix::hostile

#endif  // ROOMFIX_TESTS_TESTING_HOSTILE_CLASSES_H_
