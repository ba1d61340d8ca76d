// Where a roomfix program finds roomfix's own data files (the demo site, the
// calibration examples, the .lcm files): never the current folder, so a
// program behaves the same wherever it is started.
//
//  - Installed (the .deb, `cmake --install`): <prefix>/bin/<program> reads
//    <prefix>/share/roomfix/<relative>, the prefix being wherever the tree
//    was put (/usr, /opt/roomfix, an unpacked package).
//  - In the build tree: <build>/bin/<program> reads <source>/<relative>, so
//    an edit to config/ is seen without installing.
#ifndef ROOMFIX_MSGIO_INSTALL_PATHS_H_
#define ROOMFIX_MSGIO_INSTALL_PATHS_H_

#include <string>

namespace roomfix {

// The folder of the running executable (/proc/self/exe, symbolic links
// resolved); empty when it cannot be read.
std::string ExecutableDir();

// The data folder for an executable in exe_dir: the source tree when exe_dir
// is this build's bin folder, else exe_dir/../share/roomfix (the relative
// path between the configured install bin and data folders).
std::string DataDirFor(const std::string& exe_dir);

// DataDirFor(ExecutableDir()) + "/" + relative, e.g.
// DataFile("config/sites/demo_room.yaml").
std::string DataFile(const std::string& relative);

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_INSTALL_PATHS_H_
