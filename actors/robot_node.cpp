// A robot node: builds, starts and watches its actors.
#include "actors/robot_node.h"

namespace certislam::actors {

void RobotNodeConfig::Validate() const {
    ingest.Validate();
    scan_context.Validate();
    matcher.Validate();
    solver.Validate();
    certifier.Validate();
    mapper.Validate();
    if (quiet.count() < 0) throw std::invalid_argument("RobotNodeConfig.quiet: must be >= 0");
}

RobotNode::RobotNode(zmq::context_t& context, const TeamWiring& wiring, KeyframeSource source,
                     RobotNodeConfig config)
    : robot_(wiring.robot), config_(std::move(config)) {
    config_.Validate();
    certifier_ = std::make_unique<CertifierActor>(context, wiring, config_.certifier);
    solver_ = std::make_unique<SolverActor>(context, wiring, config_.solver);
    matcher_ = std::make_unique<LoopMatcherActor>(context, wiring, config_.matcher);
    descriptor_ = std::make_unique<DescriptorActor>(context, wiring, config_.scan_context);
    if (config_.mapping && HasEdgeEverywhere(wiring, Edge::kMap)) {
        mapper_ = std::make_unique<MapperActor>(context, wiring, config_.mapper);
        // One more local keyframe subscriber for the ingest to wait for.
        if (config_.ingest.local_subscribers > 0) ++config_.ingest.local_subscribers;
    }
    ingest_ = std::make_unique<IngestActor>(context, wiring, std::move(source), config_.ingest);
}

RobotNode::~RobotNode() { Stop(); }

void RobotNode::Start() {
    if (mapper_) mapper_->Start();
    certifier_->Start();
    solver_->Start();
    matcher_->Start();
    descriptor_->Start();
    ingest_->Start();
}

void RobotNode::RequestStop() {
    ingest_->RequestStop();
    descriptor_->RequestStop();
    matcher_->RequestStop();
    solver_->RequestStop();
    certifier_->RequestStop();
    if (mapper_) mapper_->RequestStop();
}

void RobotNode::Stop() {
    RequestStop();
    ingest_->Stop();
    descriptor_->Stop();
    matcher_->Stop();
    solver_->Stop();
    certifier_->Stop();
    if (mapper_) mapper_->Stop();
}

bool RobotNode::Done() const {
    const SolverSnapshot s = solver_->Snapshot();
    if (!ingest_->Finished() || !s.final || !s.local_ok || !s.report) return false;
    if (s.report->verdict() != v1::CERTIFICATE_VERDICT_CERTIFIED) return false;
    return std::chrono::steady_clock::now() - s.changed > config_.quiet;
}

std::uint64_t RobotNode::BytesSentToPeers() const {
    std::uint64_t total = 0;
    for (const auto& [actor, bytes] : BytesSentToPeersByActor()) total += bytes;
    return total;
}

std::map<std::string, std::uint64_t> RobotNode::BytesSentToPeersByActor() const {
    std::map<std::string, std::uint64_t> out{{"descriptor", descriptor_->BytesSentToPeers()},
                                             {"loop_matcher", matcher_->BytesSentToPeers()},
                                             {"solver", solver_->BytesSentToPeers()},
                                             {"certifier", certifier_->BytesSentToPeers()}};
    if (mapper_) out["mapper"] = mapper_->BytesSentToPeers();
    return out;
}

}  // namespace certislam::actors
