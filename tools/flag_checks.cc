#include "tools/flag_checks.h"

#include <cmath>
#include <sstream>

namespace roomfix {
namespace {

CLI::Validator FiniteNumber(double min, bool inclusive, const std::string& what) {
  return CLI::Validator(
      [min, inclusive, what](std::string& text) -> std::string {
        double v = 0.0;
        const bool number = CLI::detail::lexical_cast(text, v);
        if (number && std::isfinite(v) && (inclusive ? v >= min : v > min)) return "";
        return "expected " + what;
      },
      (std::ostringstream() << (inclusive ? "NUMBER>=" : "NUMBER>") << min).str());
}

}  // namespace

CLI::Validator FiniteAbove(double min, const std::string& what) {
  return FiniteNumber(min, false, what);
}

CLI::Validator FiniteAtLeast(double min, const std::string& what) {
  return FiniteNumber(min, true, what);
}

}  // namespace roomfix
