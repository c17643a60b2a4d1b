// GICP iterates that cycle through correspondence sets (RunGicp, registration.cpp): the matching
// alternates between 2 to 4 sets, the iterate comes back to where it was after nearly undamped
// steps, and further iterations would only repeat the cycle.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <optional>
#include <utility>

namespace certislam::slam {

/// The last accepted iterates (R, t) of one GICP run, newest first.
class GicpCycle {
  public:
    static constexpr int kLongest = 4;  ///< longest cycle told, in correspondence sets

    /// Records the iterate an accepted step moved away from.
    void Left(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
        for (int k = std::min(kept_, kLongest - 1); k > 0; --k) before_[k] = before_[k - 1];
        before_[0] = {R, t};
        kept_ = std::min(kept_ + 1, kLongest);
    }

    /// Forgets every iterate (after a damped step).
    void Clear() { kept_ = 0; }

    /// nullopt when (R, t) is not back within (same_m, same_rad) of the iterate 2 to kLongest
    /// steps before; else whether every iterate of that cycle lies within (tight_m, tight_rad)
    /// of (R, t).
    std::optional<bool> Closed(const Eigen::Matrix3d& R, const Eigen::Vector3d& t, double same_m,
                               double same_rad, double tight_m, double tight_rad) const {
        for (int k = 2; k <= kept_; ++k) {
            const auto [back_m, back_rad] = Apart(R, t, before_[k - 1]);
            if (back_m >= same_m || back_rad >= same_rad) continue;
            bool tight = true;
            for (int j = 0; j < k - 1; ++j) {
                const auto [m, rad] = Apart(R, t, before_[j]);
                tight = tight && m <= tight_m && rad <= tight_rad;
            }
            return tight;
        }
        return std::nullopt;
    }

  private:
    using Iterate = std::pair<Eigen::Matrix3d, Eigen::Vector3d>;
    /// Metres and radians between (R, t) and `b`.
    static std::pair<double, double> Apart(const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                                           const Iterate& b) {
        return {(t - b.second).norm(), Eigen::AngleAxisd(R * b.first.transpose()).angle()};
    }
    std::array<Iterate, kLongest> before_{};
    int kept_ = 0;  ///< iterates in before_, newest first
};

}  // namespace certislam::slam
