#include "tools/tool_site.h"

#include <iostream>

namespace roomfix {

bool ReportToolSite(const std::string& tool, const ToolSite& s, bool required) {
  if (s.config_failed) {
    std::cerr << tool << ": " << s.error << "\n";
    return false;
  }
  for (const auto& w : s.warnings) std::cerr << tool << ": warning: " << w << "\n";
  if (s.known) {
    std::cerr << tool << ": " << s.line << "\n";
    return true;
  }
  if (required) {
    std::cerr << tool << ": " << s.error << "\n";
    return false;
  }
  std::cerr << tool << ": note: site unknown: " << s.error << "\n";
  return true;
}

}  // namespace roomfix
