#include "core/world/gsl_errors.h"

#include <gsl/gsl_cdf.h>
#include <gtest/gtest.h>

#include <cmath>
#include <thread>
#include <vector>

#include "core/analysis/circle_fit.h"

namespace roomfix {
namespace {

// Before any test has run a fit, GSL's handler is already the one that
// does nothing: switching it off again hands back the same handler. Were it
// still GSL's default (print and abort), the two pointers would differ.
TEST(GslErrors, TheHandlerIsOffFromProcessStart) {
  gsl_error_handler_t* at_start = gsl_set_error_handler_off();
  gsl_error_handler_t* off = gsl_set_error_handler_off();
  EXPECT_EQ(at_start, off);
}

// A domain error is a NaN to check, not an abort (GSL's default handler
// would end the test binary here).
TEST(GslErrors, ADomainErrorIsAValueNotACrash) {
  EXPECT_TRUE(std::isnan(gsl_cdf_chisq_Pinv(1.5, 2.0)));
}

// Fits from several threads at once, good and refused ones interleaved:
// with the handler saved and restored around every call, one thread could
// restore GSL's aborting handler while another's fit was running. Every fit
// gives its own answer.
TEST(GslErrors, FitsRunConcurrentlyAndFailWithAMessage) {
  std::vector<analysis::TimedPoint> circle;
  for (int i = 0; i < 60; ++i) {
    const double t = i * 0.25;
    circle.push_back({t, 1.0 + 0.4 * std::cos(0.5 * t), 2.0 + 0.4 * std::sin(0.5 * t)});
  }
  const std::vector<analysis::TimedPoint> degenerate(10, analysis::TimedPoint{0.0, 1.0, 1.0});
  constexpr int kThreads = 4;
  constexpr int kRounds = 20;
  std::vector<int> usable(kThreads, 0), refused(kThreads, 0);
  std::vector<std::thread> threads;
  for (int k = 0; k < kThreads; ++k) {
    threads.emplace_back([&, k] {
      for (int round = 0; round < kRounds; ++round) {
        if (analysis::FitDriftingCircle(circle).usable) ++usable[k];
        const auto bad = analysis::FitDriftingCircle(degenerate);
        if (!bad.usable && !bad.message.empty()) ++refused[k];
      }
    });
  }
  for (auto& t : threads) t.join();
  for (int k = 0; k < kThreads; ++k) {
    EXPECT_EQ(usable[k], kRounds) << "thread " << k;
    EXPECT_EQ(refused[k], kRounds) << "thread " << k;
  }
}

}  // namespace
}  // namespace roomfix
