// What a certifier keeps of each robot: its last solver bundle (status, own edges, lifted
// block), digests that tell bundles and graphs apart, the joint graph the bundles assemble, one
// robot's share of a round's graph, and the round messages kept for re-sending.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "certify/pipeline/solver_state.h"
#include "certislam/v1/rbcd.pb.h"
#include "slam/core/loop_closure.h"
#include "slam/core/pose_graph.h"
#include "transport/message.h"

namespace certislam::actors {

/// One robot's solver bundle as a certifier keeps it.
struct CertifierBundle {
    v1::SolverStatus status;
    std::vector<slam::LoopClosure> edges;
    certify::PoseBlocks block;
    std::uint64_t digest = 0;  ///< hash of the contents (equal for re-sent copies)
};

/// Hash of a bundle's contents: phase, round session, pose ids, block and edges.
std::uint64_t BundleDigest(const CertifierBundle& b);
/// Hash of the graph a bundle describes: pose ids, rank and edges (not the block's values).
std::uint64_t GraphDigest(const CertifierBundle& b);

/// Hash of an edge set in (a, b, weights, translation) order: equal for one graph whatever order
/// its edges came in.
std::uint64_t EdgesDigest(std::vector<slam::LoopClosure> edges);

/// The joint graph and X of `bundles`; false unless there is one per robot of the team
/// (`team_size`), every robot is final at one rank with its block covering its poses, and every
/// edge's ends are known.
bool AssembleBundles(const std::map<int, CertifierBundle>& bundles, std::size_t team_size,
                     slam::PoseGraph* graph, Eigen::MatrixXd* X);

/// A robot's share of a round's graph.
struct RoundShare {
    std::vector<slam::LoopClosure> edges;         ///< every edge with an end at its poses
    std::map<slam::PoseId, Eigen::MatrixXd> far;  ///< neighbours' blocks at the far ends
    std::uint64_t round_edges = 0;                ///< edges of the round's whole graph
};
/// Robot `robot`'s share of the graph of the round's `chosen` bundles.
RoundShare ShareOf(int robot, const std::map<int, const CertifierBundle*>& chosen);

/// Keeps the round's opening (anchor), this robot's last vector and its last two partial sums
/// (a peer that lost the second pass's sums of step k waits for them while this robot waits for
/// the peer's first-pass sums of step k + 1).
void RememberSent(std::vector<transport::Message>* sent, transport::Message m);

}  // namespace certislam::actors
