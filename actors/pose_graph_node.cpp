// A pose-graph robot: builds, starts and watches its source, solver and certifier.
#include "actors/pose_graph_node.h"

#include <stdexcept>

namespace certislam::actors {

void PoseGraphNodeConfig::Validate() const {
    solver.Validate();
    certifier.Validate();
    if (quiet.count() < 0) throw std::invalid_argument("PoseGraphNodeConfig.quiet: must be >= 0");
}

PoseGraphNode::PoseGraphNode(zmq::context_t& context, const TeamWiring& wiring,
                             slam::RobotGraph graph, PoseGraphNodeConfig config)
    : robot_(wiring.robot), config_(std::move(config)) {
    config_.solver.solver.odometry_edges = false;  // every edge comes from the file
    config_.solver.rebroadcast_loops = false;      // PoseGraphActor re-sends to late joiners
    config_.Validate();
    certifier_ = std::make_unique<CertifierActor>(context, wiring, config_.certifier);
    solver_ = std::make_unique<SolverActor>(context, wiring, config_.solver);
    source_ = std::make_unique<PoseGraphActor>(context, wiring, std::move(graph));
}

PoseGraphNode::~PoseGraphNode() { Stop(); }

void PoseGraphNode::Start() {
    certifier_->Start();
    solver_->Start();
    source_->Start();
}

void PoseGraphNode::Stop() {
    source_->Stop();
    solver_->Stop();
    certifier_->Stop();
}

bool PoseGraphNode::Done() const {
    const SolverSnapshot s = solver_->Snapshot();
    if (!source_->Finished() || !s.final || !s.local_ok || !s.report) return false;
    if (s.report->verdict() != v1::CERTIFICATE_VERDICT_CERTIFIED) return false;
    return std::chrono::steady_clock::now() - s.changed > config_.quiet;
}

std::map<std::string, std::uint64_t> PoseGraphNode::BytesSentToPeersByActor() const {
    return {{"pose_graph", source_->BytesSentToPeers()},
            {"solver", solver_->BytesSentToPeers()},
            {"certifier", certifier_->BytesSentToPeers()}};
}

}  // namespace certislam::actors
