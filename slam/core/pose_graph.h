// The pose-graph types every back-end module shares: measurements, graphs, the variable layout.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

namespace certislam::slam {

/// A pose named by its robot and its index in that robot's trajectory.
struct PoseId {
    int robot = 0;  ///< robot id (0 anchors the team's common frame)
    int index = 0;  ///< keyframe index within that robot, from 0

    friend bool operator==(const PoseId&, const PoseId&) = default;
    friend auto operator<=>(const PoseId&, const PoseId&) = default;
};

/// One relative-pose measurement T~_ij = [R~ t~; 0 1] between global poses i (tail) and j (head).
/// The objective term is kappa ||R_j - R_i R~||_F^2 + tau ||t_j - t_i - R_i t~||^2 (MATH.md).
struct RelativePoseMeasurement {
    int i = 0;            ///< tail pose, global index in [0, n)
    int j = 0;            ///< head pose, global index in [0, n)
    Eigen::MatrixXd R;    ///< d x d measured rotation R~_ij (not renormalised)
    Eigen::VectorXd t;    ///< d measured translation t~_ij, metres
    double kappa = 1.0;   ///< rotation weight, > 0
    double tau = 1.0;     ///< translation weight, > 0
    double weight = 1.0;  ///< robust weight in [0, 1] (GNC); 1 for a plain least-squares edge
    bool is_known_inlier = false;  ///< odometry and other edges the robust mode must keep
};

/// A pose graph in one global index space. Poses of robot k are a contiguous index range when
/// `robot_of_pose` is built by the readers; `ids[g]` names global pose g.
struct PoseGraph {
    int d = 3;                                   ///< dimension: 2 or 3
    int n = 0;                                   ///< number of poses
    std::vector<RelativePoseMeasurement> edges;  ///< every edge, in file order, duplicates kept
    std::vector<PoseId> ids;                     ///< ids[g] = (robot, index) of global pose g
    /// Initial guess from VERTEX lines, if the file had one for every pose: d x (d+1)n,
    /// block g = [R_g t_g].
    std::optional<Eigen::MatrixXd> initial_guess;
};

/// Poses as a d x (d+1)n matrix: block g (columns g(d+1) .. g(d+1)+d) = [R_g t_g].
/// This is also the layout of the lifted variable X (r x (d+1)n, block g = [Y_g p_g]).
using PoseMatrix = Eigen::MatrixXd;

/// First column of pose g's block in a (d+1)n layout.
inline int BlockColumn(int g, int d) { return g * (d + 1); }

}  // namespace certislam::slam
