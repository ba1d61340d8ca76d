#ifndef ROOMFIX_TOOLS_FIXED_TEXT_H_
#define ROOMFIX_TOOLS_FIXED_TEXT_H_

#include <fmt/format.h>

#include <cmath>
#include <string>

namespace roomfix {

// A figure of a tool's table or report: `digits` decimals ("%.*f"), and "-"
// for one that is unknown (NaN or infinite), where printf would say "nan".
inline std::string Fixed(double v, int digits) {
  if (!std::isfinite(v)) return "-";
  return fmt::format("{:.{}f}", v, digits);
}

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_FIXED_TEXT_H_
