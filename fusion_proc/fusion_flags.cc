#include "fusion_proc/fusion_flags.h"

namespace roomfix {

void AddFusionFlags(CLI::App* app, const std::string& prefix, FusionNodeOptions* options) {
  const auto name = [&](const std::string& flag) { return "--" + prefix + flag; };
  fusion::PoseFilterOptions& filter = options->filter;
  app->add_option(name("camera-channel"), options->camera_channel, "Camera poses")
      ->capture_default_str();
  app->add_option(name("ultrasound-channel"), options->ultrasound_channel, "Ultrasonic poses")
      ->capture_default_str();
  app->add_option(name("fused-channel"), options->fused_channel, "Fused poses")
      ->capture_default_str();
  app->add_option(name("rate"), options->rate_hz,
                  "Also publish each robot's prediction to now at this rate, Hz (0: only at "
                  "measurements)")
      ->capture_default_str();
  app->add_option(name("forget-after"), options->forget_after_s,
                  "Drop a robot's track after this long without a measurement, s")
      ->capture_default_str();
  app->add_option(name("lost-after"), filter.lost_after_s,
                  "A robot is lost when no measurement was accepted for this long, s")
      ->capture_default_str();
  app->add_option(name("q-accel"), filter.q_accel_m_per_s1_5,
                  "Process noise: white acceleration density, m/s^2/sqrt(Hz)")
      ->capture_default_str();
  app->add_option(name("q-turn"), filter.q_turn_rad_per_s1_5,
                  "Process noise: white angular acceleration density, rad/s^2/sqrt(Hz)")
      ->capture_default_str();
  app->add_option(name("ultrasound-sigma-floor"), filter.ultrasound_sigma_floor_m,
                  "Smallest standard deviation granted to an ultrasonic position, m")
      ->capture_default_str();
  app->add_option(name("ultrasound-inflation"), filter.ultrasound_inflation,
                  "Factor on the ultrasonic covariances")
      ->capture_default_str();
  app->add_option(name("camera-sigma-floor"), filter.camera_sigma_floor_m,
                  "Smallest standard deviation granted to a camera position, m")
      ->capture_default_str();
  app->add_option(name("camera-calibration-sigma"), filter.camera_calibration_sigma_m,
                  "Several cameras: each camera calibration's error, m, added to its poses' "
                  "covariance (docs/fusion.md, \"Several cameras\")")
      ->capture_default_str();
  app->add_option(name("camera-bias-time"), filter.camera_bias_time_s,
                  "Correlation time of the camera's correlated error (the robot's tilt, its "
                  "sigma from the site), s; 0: every camera error white (docs/fusion.md)")
      ->capture_default_str();
  app->add_option(name("gate"), filter.gate_chi2_2dof,
                  "Gate on the squared Mahalanobis distance of a position (chi-square, 2 dof)")
      ->capture_default_str();
  app->add_option(name("reopen-after"), filter.reopen_after_rejections,
                  "Consecutive rejections after which the gate reopens")
      ->capture_default_str();
  app->add_option(name("reopen-after-time"), filter.reopen_after_s,
                  "Or after two or more consecutive rejections spanning this long, s (0: the "
                  "count alone)")
      ->capture_default_str();
  app->add_option(name("history"), filter.history_s,
                  "How far back a late measurement is still applied at its time, s")
      ->capture_default_str();
}

}  // namespace roomfix
