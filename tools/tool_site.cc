#include "tools/tool_site.h"

#include <iostream>

#include "core/world/file_io.h"

namespace roomfix {

ToolSite ResolveSiteForLog(const std::string& config_path, const std::string& log_path) {
  ToolSite s;
  if (!config_path.empty()) {
    // Told apart from a log without SITE: a bad --config stops every tool.
    LoadedSite probe;
    if (!LoadSiteWithTexts(config_path, &probe, &s.error)) {
      s.config_failed = true;
      return s;
    }
  }
  s.known = ResolveToolSite(config_path, log_path, &s.site, &s.line, &s.warnings, &s.error);
  s.source = config_path.empty() ? "log" : "--config";
  return s;
}

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
