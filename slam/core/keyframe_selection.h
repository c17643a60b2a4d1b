// Keyframe selection by travelled distance and rotation, as LIO-SAM decides when to save one.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <vector>

namespace certislam::slam {

/// When a new pose becomes a keyframe (LIO-SAM's saveFrame(): 1 m / 0.2 rad by default).
struct KeyframeSelectionConfig {
    double min_translation_m = 1.0;  ///< distance from the last keyframe that makes one, >= 0
    double min_rotation_rad = 0.2;   ///< rotation from the last keyframe that makes one, >= 0

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Streaming selector: the first pose is a keyframe; a later one is when it has moved at least
/// min_translation_m or turned at least min_rotation_rad (angle of the relative rotation)
/// since the last keyframe.
class KeyframeSelector {
  public:
    /// Validates `config` (throws std::invalid_argument).
    explicit KeyframeSelector(const KeyframeSelectionConfig& config = {});

    /// True when `T_odom_sensor` is a keyframe; it then becomes the reference for the next.
    bool Accept(const Eigen::Isometry3d& T_odom_sensor);

    /// Forgets the last keyframe: the next pose is accepted.
    void Reset() { last_.reset(); }

  private:
    KeyframeSelectionConfig config_;
    std::optional<Eigen::Isometry3d> last_;
};

/// Indices of the keyframes among `poses` (T_odom_sensor in time order).
std::vector<int> SelectKeyframes(const std::vector<Eigen::Isometry3d>& poses,
                                 const KeyframeSelectionConfig& config = {});

}  // namespace certislam::slam
