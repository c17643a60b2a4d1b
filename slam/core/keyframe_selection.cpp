#include "slam/core/keyframe_selection.h"

#include <stdexcept>
#include <string>

namespace certislam::slam {

void KeyframeSelectionConfig::Validate() const {
    if (!(min_translation_m >= 0.0)) {
        throw std::invalid_argument("KeyframeSelectionConfig.min_translation_m = " +
                                    std::to_string(min_translation_m) + ": must be >= 0");
    }
    if (!(min_rotation_rad >= 0.0)) {
        throw std::invalid_argument("KeyframeSelectionConfig.min_rotation_rad = " +
                                    std::to_string(min_rotation_rad) + ": must be >= 0");
    }
}

KeyframeSelector::KeyframeSelector(const KeyframeSelectionConfig& config) : config_(config) {
    config_.Validate();
}

bool KeyframeSelector::Accept(const Eigen::Isometry3d& T_odom_sensor) {
    if (last_) {
        const Eigen::Isometry3d T_last_current = last_->inverse() * T_odom_sensor;
        const double angle = Eigen::AngleAxisd(T_last_current.linear()).angle();
        if (T_last_current.translation().norm() < config_.min_translation_m &&
            angle < config_.min_rotation_rad) {
            return false;
        }
    }
    last_ = T_odom_sensor;
    return true;
}

std::vector<int> SelectKeyframes(const std::vector<Eigen::Isometry3d>& poses,
                                 const KeyframeSelectionConfig& config) {
    KeyframeSelector selector(config);
    std::vector<int> selected;
    for (size_t i = 0; i < poses.size(); ++i) {
        if (selector.Accept(poses[i])) selected.push_back(static_cast<int>(i));
    }
    return selected;
}

}  // namespace certislam::slam
