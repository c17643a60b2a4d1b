// The edge weights' settings: checked once, named in every message.
#include "certify/pipeline/edge_noise.h"

#include <stdexcept>
#include <string>

namespace certislam::certify {
namespace {

void Require(bool ok, const std::string& what, double value, const std::string& rule) {
    if (!ok) throw std::invalid_argument(what + " = " + std::to_string(value) + ": " + rule);
}

}  // namespace

void EdgeNoiseConfig::Validate() const {
    Require(odometry_sigma_t_m > 0, "EdgeNoiseConfig.odometry_sigma_t_m", odometry_sigma_t_m,
            "must be > 0");
    Require(odometry_sigma_r_rad > 0, "EdgeNoiseConfig.odometry_sigma_r_rad", odometry_sigma_r_rad,
            "must be > 0");
    Require(loop_sigma_t_m > 0, "EdgeNoiseConfig.loop_sigma_t_m", loop_sigma_t_m, "must be > 0");
    Require(loop_sigma_r_rad > 0, "EdgeNoiseConfig.loop_sigma_r_rad", loop_sigma_r_rad,
            "must be > 0");
}

}  // namespace certislam::certify
