#ifndef ROOMFIX_CORE_WORLD_ACOUSTIC_PATHS_H_
#define ROOMFIX_CORE_WORLD_ACOUSTIC_PATHS_H_

#include <array>
#include <vector>

#include "core/world/air_model.h"
#include "core/world/site.h"

namespace roomfix {

// Which way a beacon's pulse reaches a receiver in a room with obstacles
// (the site's `obstacles`): non-line-of-sight from geometry, for the
// simulator's ranges and the firmware-in-the-loop acoustic model alike.
//
// The model (docs/trilateration.md, "Obstacles and non-line-of-sight"):
//  - the direct path is the segment beacon -> receiver; it is blocked when it
//    passes through an obstacle (a box or a vertical cylinder, with their
//    vertical extents). At 40 kHz the wavelength is 8.6 mm, so diffraction
//    round a 10 cm or larger obstacle is tens of dB down and not modelled;
//  - otherwise the receiver hears the shortest first-order reflection whose
//    two legs are both unblocked (image sources): the four walls, the floor,
//    the ceiling and the faces of boxes are mirrors. A cylinder is convex:
//    its echo spreads over an angle of order (leg / radius), tens of dB below
//    a plane's, so it is not a mirror here (it still blocks);
//  - a path is heard when its level is above the receivers' detection
//    threshold. Its loss against the level 1 m from the beacon is spherical
//    spreading 20 log10(L / 1 m), the air's absorption alpha L (ISO 9613-1,
//    AirAbsorptionDbPerM) and -10 log10(1 - a) per reflection (a: the site's
//    acoustics.wall_absorption, for walls and obstacle faces alike); the
//    threshold sits acoustics.detection_margin_db below the weakest direct
//    arrival in the room (ComputeRoomDecay), so every direct path is heard
//    and a reflection is heard while its extra loss stays inside the margin;
//  - nothing else: no second-order reflections (each costs another
//    reflection's loss and a longer detour, and the detector latches on the
//    first arrival above threshold, which is the shortest heard path).
// The result is persistent exactly as long as the geometry is: a robot behind
// a pillar stays blocked from the same receiver until it comes out.
struct AudiblePath {
  enum class Kind { kDirect, kReflected, kNone };
  enum class Mirror { kNone, kWall, kFloor, kCeiling, kObstacleFace };
  Kind kind = Kind::kNone;
  // Length of the path the pulse travelled, m (NaN for kNone).
  double length_m = 0.0;
  // Loss against the level 1 m from the beacon, dB (spreading, air,
  // reflection), and the level left above the detection threshold, dB.
  double loss_db = 0.0;
  double level_db = 0.0;
  // The mirror of a kReflected path, the obstacle it belongs to (index into
  // Site::obstacles, -1 for the room's surfaces) and the reflection point.
  Mirror mirror = Mirror::kNone;
  int obstacle_index = -1;
  std::array<double, 3> reflection_point_m{};
  // Length of the direct segment, blocked or not, m: length_m minus this is
  // the detour a reflected range reads long by.
  double direct_m = 0.0;
};
const char* AudiblePathKindName(AudiblePath::Kind kind);

// The room's surfaces and obstacles at one temperature; cheap to copy.
// Pure: time is an argument (moving obstacles are placed at t_s, seconds of
// simulation time as for simulation.robots).
class AcousticScene {
 public:
  AcousticScene(const Site& site, double temperature_c);

  // The first arrival at `receiver_m` of a pulse fired at `beacon_m` (room
  // frame, metres). Work: (6 + 6 boxes) mirrors times (1 + obstacles)
  // segment tests, at most about 6 600 for the site's cap of 32 obstacles.
  AudiblePath ShortestAudiblePath(double t_s, const std::array<double, 3>& beacon_m,
                                  const std::array<double, 3>& receiver_m) const;
  // True when the segment a -> b passes through an obstacle placed at t_s
  // (touching a surface or ending on one is not passing through).
  bool Blocked(double t_s, const std::array<double, 3>& a, const std::array<double, 3>& b) const;

  const RoomDecay& decay() const { return decay_; }

 private:
  struct Placed {
    Obstacle obstacle;
    std::array<double, 2> centre_m{};
  };
  std::vector<Placed> PlaceAt(double t_s) const;
  static bool BlockedBy(const std::vector<Placed>& placed, const std::array<double, 3>& a,
                        const std::array<double, 3>& b);

  Room room_;
  std::vector<Obstacle> obstacles_;
  RoomDecay decay_;
  // -10 log10(1 - wall_absorption): the loss of one reflection, dB.
  double reflection_loss_db_ = 0.0;
};

// One-call form for a fixed scene: the site's obstacles at t_s, air at
// temperature_c.
AudiblePath ShortestAudiblePath(const Site& site, const std::array<double, 3>& beacon_m,
                                const std::array<double, 3>& receiver_m, double t_s = 0.0,
                                double temperature_c = 20.0);

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_ACOUSTIC_PATHS_H_
