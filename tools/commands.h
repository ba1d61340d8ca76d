#ifndef ROOMFIX_TOOLS_COMMANDS_H_
#define ROOMFIX_TOOLS_COMMANDS_H_

namespace CLI {
class App;
}

namespace roomfix {

// Each subcommand of `roomfix` registers itself on the top-level app and sets
// *exit_code from its callback (roomfix_main.cc adds them in this order;
// docs/architecture.md lists what each does). The benchmarks are a program
// of their own, roomfix_bench (bench/commands.h).
void AddVersionCommand(CLI::App* app, int* exit_code);
void AddCheckConfigCommand(CLI::App* app, int* exit_code);
void AddLogInfoCommand(CLI::App* app, int* exit_code);
void AddListenCommand(CLI::App* app, int* exit_code);
void AddSolveCommand(CLI::App* app, int* exit_code);
void AddCompareCommand(CLI::App* app, int* exit_code);
void AddFramesCommand(CLI::App* app, int* exit_code);
void AddAnalyzeCommand(CLI::App* app, int* exit_code);
void AddCalibrateCommand(CLI::App* app, int* exit_code);
void AddMapCommand(CLI::App* app, int* exit_code);
void AddRenderCameraCommand(CLI::App* app, int* exit_code);
// roomfix detect IMAGE --site SITE --out OVERLAY.png: the detector view of a
// saved frame (tools/detect_command.cc, docs/camera.md).
void AddDetectCommand(CLI::App* app, int* exit_code);
void AddSurveyCommand(CLI::App* app, int* exit_code);
void AddReplayCommand(CLI::App* app, int* exit_code);
// roomfix export LOG --csv DIR (export_command.cc, csv_export.h).
void AddExportCommand(CLI::App* app, int* exit_code);
// roomfix devices: the beacons' and receivers' EEPROM images from the site
// (tools/devices_command.cc, docs/devices.md).
void AddDevicesCommand(CLI::App* app, int* exit_code);
// roomfix colours: colour classes learned from frames (colours_command.cc).
void AddColoursCommand(CLI::App* app, int* exit_code);
// roomfix grab: frames from a site camera's device, opened as camera_proc
// opens it (tools/grab_command.cc, docs/camera.md "Grabbing frames").
void AddGrabCommand(CLI::App* app, int* exit_code);

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_COMMANDS_H_
