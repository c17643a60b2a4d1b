// One robot's asynchronous RBCD state: local graph (own poses + neighbour poses its edges touch),
// warm starts, alignment to the lower robot at first encounter, anchored rounding.
#include "certify/pipeline/solver_state.h"

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <string>

#include "slam/backend/chordal.h"
#include "slam/backend/rounding.h"
#include "slam/core/partition.h"

namespace certislam::certify {
namespace {

constexpr int kBlock = 4;  // d + 1 columns per pose (d = 3)

/// Rows padded with zeros (or cut) to rank r: a rank-r' lifted pose embeds in rank r >= r'.
Eigen::MatrixXd AtRank(const Eigen::MatrixXd& X, int r) {
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(r, X.cols());
    const int rows = std::min<int>(r, static_cast<int>(X.rows()));
    out.topRows(rows) = X.topRows(rows);
    return out;
}

Eigen::MatrixXd Lift(const Eigen::Isometry3d& T, int r) {
    Eigen::MatrixXd X = Eigen::MatrixXd::Zero(r, kBlock);
    X.topLeftCorner<3, 3>() = T.linear();
    X.block<3, 1>(0, 3) = T.translation();
    return X;
}

/// T with its rotation projected onto SO(3): a prediction through a loop whose measured R~ is not
/// a rotation (merged parallel edges, slam::MergeParallelEdges) stays a pose.
Eigen::Isometry3d Rigid(Eigen::Isometry3d T) {
    T.linear() = slam::ProjectToRotation(Eigen::Matrix3d(T.linear()));
    return T;
}

bool SameEnds(const slam::LoopClosure& x, const slam::LoopClosure& y) {
    return x.a == y.a && x.b == y.b;
}

}  // namespace

Eigen::MatrixXd LiftedTimes(const Eigen::MatrixXd& X_a, const Eigen::Isometry3d& T) {
    Eigen::MatrixXd out(X_a.rows(), kBlock);
    out.leftCols<3>() = X_a.leftCols<3>() * T.linear();
    out.col(3) = X_a.leftCols<3>() * T.translation() + X_a.col(3);
    return out;
}

Eigen::Isometry3d LiftedRelative(const Eigen::MatrixXd& X_a, const Eigen::MatrixXd& X_b) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const Eigen::MatrixXd Ya = X_a.leftCols<3>();
    T.linear() = slam::ProjectToRotation(Ya.transpose() * X_b.leftCols<3>());
    T.translation() = Ya.transpose() * (X_b.col(3) - X_a.col(3));
    return T;
}

int ComponentAnchor(int robot, const std::vector<slam::LoopClosure>& inter_robot_loops) {
    std::set<int> reached{robot};
    for (bool grew = true; grew;) {
        grew = false;
        for (const auto& l : inter_robot_loops) {
            const bool a = reached.count(l.a.robot) > 0, b = reached.count(l.b.robot) > 0;
            if (a != b) {
                reached.insert(a ? l.b.robot : l.a.robot);
                grew = true;
            }
        }
    }
    return *reached.begin();
}

void SolverConfig::Validate() const {
    if (rank < 3)
        throw std::invalid_argument("SolverConfig.rank = " + std::to_string(rank) +
                                    ": must be >= 3");
    noise.Validate();
    rbcd.Validate();
}

struct SolverState::Impl {
    int robot = 0;
    SolverConfig config;
    int rank = 5;
    int staircase_level = 0;
    int frame_robot = 0;  ///< whose frame the block is in (self until aligned to a lower robot)
    std::vector<Eigen::Isometry3d> odom;
    Eigen::MatrixXd X;                            ///< r x 4n own block
    std::vector<slam::LoopClosure> loops;         ///< every loop touching this robot
    std::map<slam::PoseId, Eigen::MatrixXd> nbr;  ///< neighbours' last known lifted poses
    std::optional<slam::RbcdAgent> agent;
    std::vector<slam::PoseId> local_nbr;  ///< neighbour poses in the agent's local order
    bool dirty = true;
    /// The last Trajectory and the block and anchor pose it rounded: an actor asks every tick,
    /// mostly while nothing moved, and rounding is an SVD per pose.
    struct {
        Eigen::MatrixXd X, X0;
        std::vector<Eigen::Isometry3d> poses;
    } mutable rounded;

    int n() const { return static_cast<int>(odom.size()); }
    bool Own(const slam::PoseId& id) const { return id.robot == robot; }
    bool Active(const slam::LoopClosure& l) const {
        return (!Own(l.a) || l.a.index < n()) && (!Own(l.b) || l.b.index < n());
    }
    Eigen::MatrixXd OwnPose(int k) const { return X.middleCols(kBlock * k, kBlock); }

    double OdomKappa() const { return slam::RotationWeight(config.noise.odometry_sigma_r_rad); }
    double OdomTau() const { return slam::TranslationWeight(config.noise.odometry_sigma_t_m); }

    /// Lifted pose of a neighbour pose: last heard, else predicted through the loop.
    Eigen::MatrixXd NeighbourPose(const slam::PoseId& id) const {
        if (auto it = nbr.find(id); it != nbr.end()) return AtRank(it->second, rank);
        for (const auto& l : loops) {
            if (!Active(l)) continue;
            if (l.b == id && Own(l.a)) return LiftedTimes(OwnPose(l.a.index), Rigid(l.T_a_b));
            if (l.a == id && Own(l.b)) {
                return LiftedTimes(OwnPose(l.b.index), Rigid(l.T_a_b).inverse());
            }
        }
        return Lift(Eigen::Isometry3d::Identity(), rank);
    }

    /// First encounter with a lower robot: move the whole block into its frame through the loop
    /// (one rigid motion in the lifted space, DiSCo-style), so RBCD starts near the optimum.
    void AlignToLowerRobot() {
        for (const auto& l : loops) {
            if (!Active(l) || !(l.a.robot != l.b.robot)) continue;
            const slam::PoseId other = Own(l.a) ? l.b : l.a;
            if (other.robot >= frame_robot || !nbr.count(other)) continue;
            const int i = Own(l.a) ? l.a.index : l.b.index;
            const Eigen::Isometry3d T_other_own =
                Own(l.a) ? Rigid(l.T_a_b).inverse() : Rigid(l.T_a_b);
            const Eigen::MatrixXd X_i = LiftedTimes(AtRank(nbr.at(other), rank), T_other_own);
            Eigen::MatrixXd moved(X.rows(), X.cols());
            for (int k = 0; k < n(); ++k) {
                moved.middleCols(kBlock * k, kBlock) =
                    LiftedTimes(X_i, LiftedRelative(OwnPose(i), OwnPose(k)));
            }
            X = moved;
            frame_robot = other.robot;
            dirty = true;
        }
    }

    void Rebuild() {
        std::set<slam::PoseId> others;
        for (const auto& l : loops) {
            if (!Active(l)) continue;
            if (!Own(l.a)) others.insert(l.a);
            if (!Own(l.b)) others.insert(l.b);
        }
        local_nbr.assign(others.begin(), others.end());
        std::map<slam::PoseId, int> local;
        slam::PoseGraph graph;
        graph.d = 3;
        graph.n = n() + static_cast<int>(local_nbr.size());
        for (int k = 0; k < n(); ++k) {
            graph.ids.push_back({robot, k});
            local[{robot, k}] = k;
        }
        for (size_t k = 0; k < local_nbr.size(); ++k) {
            graph.ids.push_back(local_nbr[k]);
            local[local_nbr[k]] = n() + static_cast<int>(k);
        }
        for (int k = 0; config.odometry_edges && k + 1 < n(); ++k) {
            auto e = slam::MeasurementOf(k, k + 1, odom[k].inverse() * odom[k + 1], OdomKappa(),
                                         OdomTau());
            e.is_known_inlier = true;
            graph.edges.push_back(e);
        }
        for (const auto& l : loops) {
            if (Active(l)) {
                graph.edges.push_back(slam::MeasurementOf(l, local.at(l.a), local.at(l.b)));
            }
        }
        dirty = false;
        if (graph.edges.empty()) {
            agent.reset();
            return;
        }
        slam::Partition partition{{0, n()}};
        if (!local_nbr.empty()) partition.begin.push_back(graph.n);
        agent.emplace(graph, partition, 0, rank, config.rbcd);
        agent->SetBlock(X);
        dirty = false;
    }

    Eigen::MatrixXd NeighbourBlocks() const {
        Eigen::MatrixXd out(rank, kBlock * static_cast<int>(local_nbr.size()));
        for (size_t k = 0; k < local_nbr.size(); ++k) {
            out.middleCols(kBlock * k, kBlock) = NeighbourPose(local_nbr[k]);
        }
        return out;
    }

    /// This robot's share of f: edges whose tail is an own pose (each edge counted once team-wide).
    double OwnCost() const {
        const auto pose = [&](const slam::PoseId& id) {
            return Own(id) ? OwnPose(id.index) : NeighbourPose(id);
        };
        const auto term = [](const Eigen::MatrixXd& Xi, const Eigen::MatrixXd& Xj,
                             const Eigen::Isometry3d& T, double kappa, double tau) {
            const Eigen::MatrixXd Yi = Xi.leftCols<3>();
            return kappa * (Xj.leftCols<3>() - Yi * T.linear()).squaredNorm() +
                   tau * (Xj.col(3) - Xi.col(3) - Yi * T.translation()).squaredNorm();
        };
        double f = 0.0;
        for (int k = 0; config.odometry_edges && k + 1 < n(); ++k) {
            f += term(OwnPose(k), OwnPose(k + 1), odom[k].inverse() * odom[k + 1], OdomKappa(),
                      OdomTau());
        }
        for (const auto& l : loops) {
            if (Active(l) && Own(l.a)) f += term(pose(l.a), pose(l.b), l.T_a_b, l.kappa, l.tau);
        }
        return f;
    }
};

SolverState::SolverState(int robot, SolverConfig config) : impl_(std::make_unique<Impl>()) {
    config.Validate();
    impl_->robot = robot;
    impl_->rank = config.rank;
    impl_->frame_robot = robot;
    impl_->config = config;
    impl_->X.resize(impl_->rank, 0);
}
SolverState::~SolverState() = default;
SolverState::SolverState(SolverState&&) noexcept = default;
SolverState& SolverState::operator=(SolverState&&) noexcept = default;

bool SolverState::AddKeyframe(int index, const Eigen::Isometry3d& T_odom) {
    Impl& m = *impl_;
    if (index != m.n()) return false;
    Eigen::MatrixXd X_new =
        m.odom.empty() ? Lift(T_odom, m.rank)
                       : LiftedTimes(m.OwnPose(m.n() - 1), m.odom.back().inverse() * T_odom);
    m.X.conservativeResize(m.rank, m.X.cols() + kBlock);
    m.X.rightCols<kBlock>() = X_new;
    m.odom.push_back(T_odom);
    m.dirty = true;
    return true;
}

bool SolverState::AddLoop(const slam::LoopClosure& loop) {
    Impl& m = *impl_;
    if (!m.Own(loop.a) && !m.Own(loop.b)) return false;
    for (const auto& l : m.loops) {
        if (SameEnds(l, loop)) return false;
    }
    m.loops.push_back(loop);
    m.dirty = m.dirty || m.Active(loop);
    return true;
}

bool SolverState::RemoveLoop(const slam::PoseId& a, const slam::PoseId& b) {
    Impl& m = *impl_;
    const auto it = std::find_if(m.loops.begin(), m.loops.end(),
                                 [&](const slam::LoopClosure& l) { return l.a == a && l.b == b; });
    if (it == m.loops.end()) return false;
    m.dirty = m.dirty || m.Active(*it);
    m.loops.erase(it);
    return true;
}

void SolverState::SetNeighbourPoses(const PoseBlocks& poses) {
    Impl& m = *impl_;
    for (size_t k = 0; k < poses.ids.size(); ++k) {
        if (m.Own(poses.ids[k])) continue;
        m.nbr[poses.ids[k]] = poses.blocks.middleCols(kBlock * k, kBlock);
    }
}

bool SolverState::AdoptBlock(const Eigen::MatrixXd& X_own, int staircase_level) {
    Impl& m = *impl_;
    if (X_own.cols() != m.X.cols() || X_own.rows() < m.rank) return false;
    m.X = X_own;
    m.rank = static_cast<int>(X_own.rows());
    m.staircase_level = staircase_level;
    m.dirty = true;
    return true;
}

SolverStepResult SolverState::Step(double team_cost, double tolerance_scale) {
    return StepTo(tolerance_scale * impl_->config.rbcd.rel_grad_tol * std::max(1.0, team_cost));
}

SolverStepResult SolverState::StepTo(double tol) {
    Impl& m = *impl_;
    SolverStepResult result;
    if (m.n() == 0) return result;
    const int frame_before = m.frame_robot;
    m.AlignToLowerRobot();
    if (m.dirty || m.frame_robot != frame_before) {
        m.Rebuild();
        result.rebuilt = true;
    }
    if (!m.agent) {  // no edge yet (one pose, loops to poses still to come): nothing to optimise
        result.status = SolverStepResult::Status::kLocalOk;
        return result;
    }
    m.agent->SetNeighborPoses(m.NeighbourBlocks());
    const slam::RbcdAgentStatus s = m.agent->Update(tol);
    m.X = m.agent->Block();
    result.grad_norm = s.rtr_iterations == 0 ? s.grad_norm_before : s.grad_norm_after;
    result.cost = m.OwnCost();
    using A = slam::RbcdAgentStatus::Status;
    result.moved = s.status == A::kImproved;
    result.status = s.status == A::kImproved    ? SolverStepResult::Status::kImproved
                    : s.status == A::kConverged ? SolverStepResult::Status::kLocalOk
                                                : SolverStepResult::Status::kStuck;
    if (result.status != SolverStepResult::Status::kLocalOk && result.grad_norm <= tol) {
        result.status = SolverStepResult::Status::kLocalOk;
    }
    return result;
}

SolverStepResult SolverState::Evaluate() {
    Impl& m = *impl_;
    SolverStepResult result;
    if (m.n() == 0) return result;
    if (m.dirty) m.Rebuild();
    result.status = SolverStepResult::Status::kLocalOk;
    result.cost = m.OwnCost();
    if (m.agent) {
        m.agent->SetNeighborPoses(m.NeighbourBlocks());
        result.grad_norm = m.agent->BlockGradNorm();
    }
    return result;
}

void SolverState::SetOwnBlock(const Eigen::MatrixXd& X_own) {
    Impl& m = *impl_;
    if (X_own.rows() != m.X.rows() || X_own.cols() != m.X.cols()) return;
    m.X = X_own;
    if (m.agent && !m.dirty) m.agent->SetBlock(m.X);
}

bool SolverState::LocalChordalStart() {
    Impl& m = *impl_;
    slam::PoseGraph graph;
    graph.d = 3;
    graph.n = m.n();
    for (int k = 0; m.config.odometry_edges && k + 1 < m.n(); ++k) {
        graph.edges.push_back(slam::MeasurementOf(k, k + 1, m.odom[k].inverse() * m.odom[k + 1],
                                                  m.OdomKappa(), m.OdomTau()));
    }
    for (const auto& l : m.loops) {
        if (m.Own(l.a) && m.Own(l.b) && m.Active(l)) {
            graph.edges.push_back(slam::MeasurementOf(l, l.a.index, l.b.index));
        }
    }
    std::vector<int> root(m.n());  // union-find: chordal needs every own pose joined
    for (int k = 0; k < m.n(); ++k) root[k] = k;
    const auto find = [&](int k) {
        while (root[k] != k) k = root[k] = root[root[k]];
        return k;
    };
    int components = m.n();
    for (const auto& e : graph.edges) {
        const int a = find(e.i), b = find(e.j);
        if (a != b) {
            root[a] = b;
            --components;
        }
    }
    if (m.n() < 2 || components != 1) return false;
    const slam::PoseMatrix P = slam::ChordalInitialization(graph);
    if (!P.allFinite()) return false;
    const Eigen::MatrixXd X0 = m.OwnPose(0);
    const auto pose = [&](int k) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = P.block<3, 3>(0, kBlock * k);
        T.translation() = P.block<3, 1>(0, kBlock * k + 3);
        return T;
    };
    const Eigen::Isometry3d T0_inv = pose(0).inverse();
    for (int k = 0; k < m.n(); ++k) {
        m.X.middleCols(kBlock * k, kBlock) = LiftedTimes(X0, T0_inv * pose(k));
    }
    m.dirty = true;
    return true;
}

bool SolverState::AlignToLowerNeighbour() {
    Impl& m = *impl_;
    const int before = m.frame_robot;
    m.AlignToLowerRobot();
    return m.frame_robot != before;
}

PoseBlocks SolverState::PublicPoses(std::uint64_t iteration) const {
    const Impl& m = *impl_;
    std::set<int> indices;
    if (m.n() > 0) indices.insert(0);
    for (const auto& l : m.loops) {
        if (!m.Active(l) || l.a.robot == l.b.robot) continue;
        indices.insert(m.Own(l.a) ? l.a.index : l.b.index);
    }
    PoseBlocks out;
    out.iteration = iteration;
    out.staircase_level = m.staircase_level;
    out.blocks.resize(m.rank, kBlock * static_cast<int>(indices.size()));
    int k = 0;
    for (int i : indices) {
        out.ids.push_back({m.robot, i});
        out.blocks.middleCols(kBlock * k++, kBlock) = m.OwnPose(i);
    }
    return out;
}

PoseBlocks SolverState::FullBlock(std::uint64_t iteration) const {
    const Impl& m = *impl_;
    PoseBlocks out;
    out.iteration = iteration;
    out.staircase_level = m.staircase_level;
    out.blocks = m.X;
    for (int i = 0; i < m.n(); ++i) out.ids.push_back({m.robot, i});
    return out;
}

PoseBlocks SolverState::NeighbourBlocks() const {
    const Impl& m = *impl_;
    PoseBlocks out{{}, Eigen::MatrixXd(m.rank, kBlock * int(m.nbr.size())), 0, m.staircase_level};
    int k = 0;
    for (const auto& [id, block] : m.nbr) {
        out.ids.push_back(id);
        out.blocks.middleCols(kBlock * k++, kBlock) = AtRank(block, m.rank);
    }
    return out;
}

std::vector<Eigen::Isometry3d> SolverState::Trajectory(int anchor, int* anchor_used) const {
    const Impl& m = *impl_;
    std::vector<Eigen::Isometry3d> out;
    if (m.n() == 0) return out;
    Eigen::MatrixXd X0 = m.OwnPose(0);
    int used = m.robot;
    if (anchor != m.robot) {
        if (auto it = m.nbr.find({anchor, 0}); it != m.nbr.end()) {
            X0 = AtRank(it->second, m.rank);
            used = anchor;
        }
    }
    if (anchor_used != nullptr) *anchor_used = used;
    auto& cache = m.rounded;
    if (cache.X.size() == m.X.size() && cache.X0.size() == X0.size() && cache.X == m.X &&
        cache.X0 == X0) {
        return cache.poses;
    }
    for (int k = 0; k < m.n(); ++k) out.push_back(LiftedRelative(X0, m.OwnPose(k)));
    cache.X = m.X;
    cache.X0 = X0;
    cache.poses = out;
    return out;
}

std::set<int> SolverState::Neighbours() const {
    std::set<int> out;
    for (const auto& l : impl_->loops) {
        if (l.a.robot != l.b.robot) out.insert(impl_->Own(l.a) ? l.b.robot : l.a.robot);
    }
    return out;
}

std::vector<slam::LoopClosure> SolverState::InterRobotLoops() const {
    std::vector<slam::LoopClosure> out;
    for (const auto& l : impl_->loops) {
        if (l.inter_robot()) out.push_back(l);
    }
    return out;
}

std::vector<slam::LoopClosure> SolverState::OwnEdges() const {
    const Impl& m = *impl_;
    std::vector<slam::LoopClosure> out;
    for (int k = 0; m.config.odometry_edges && k + 1 < m.n(); ++k) {
        slam::LoopClosure e;
        e.a = {m.robot, k};
        e.b = {m.robot, k + 1};
        e.T_a_b = m.odom[k].inverse() * m.odom[k + 1];
        e.kappa = m.OdomKappa();
        e.tau = m.OdomTau();
        out.push_back(e);
    }
    std::copy_if(m.loops.begin(), m.loops.end(), std::back_inserter(out),
                 [&m](const slam::LoopClosure& l) { return m.Own(l.a) && m.Active(l); });
    return out;
}

int SolverState::NumPoses() const { return impl_->n(); }
int SolverState::Rank() const { return impl_->rank; }
int SolverState::StaircaseLevel() const { return impl_->staircase_level; }
int SolverState::robot() const { return impl_->robot; }

}  // namespace certislam::certify
