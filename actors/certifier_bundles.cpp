// Certifier bundles: digests (FNV-1a), the joint graph, a robot's round share, re-send memory.
#include "actors/certifier_bundles.h"

#include <Eigen/Core>
#include <algorithm>
#include <iterator>
#include <tuple>

#include "certislam/v1/certificate.pb.h"
#include "slam/core/loop_closure.h"

namespace certislam::actors {
namespace {

constexpr int kBlock = 4;  ///< columns per pose (d + 1, d = 3)

/// FNV-1a over raw bytes.
void Mix(std::uint64_t* h, const void* data, std::size_t size) {
    const auto* bytes = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) *h = (*h ^ bytes[i]) * 1099511628211ull;
}

/// Mixes every edge's ends, measurement and weights (both digests hash the graph the same way).
template <typename Edges>
void MixEdges(std::uint64_t* h, const Edges& edges) {
    for (const auto& e : edges) {
        Mix(h, &e.a, sizeof(e.a));
        Mix(h, &e.b, sizeof(e.b));
        Mix(h, e.T_a_b.matrix().data(), sizeof(double) * 16);
        Mix(h, &e.kappa, sizeof(e.kappa));
        Mix(h, &e.tau, sizeof(e.tau));
    }
}

}  // namespace

std::uint64_t BundleDigest(const CertifierBundle& b) {
    std::uint64_t h = 14695981039346656037ull;
    const int phase = b.status.phase();
    Mix(&h, &phase, sizeof(phase));
    const std::uint64_t session = b.status.round_session();
    Mix(&h, &session, sizeof(session));
    for (const auto& id : b.block.ids) Mix(&h, &id, sizeof(id));
    const Eigen::Index dims[2] = {b.block.blocks.rows(), b.block.blocks.cols()};
    Mix(&h, dims, sizeof(dims));
    Mix(&h, b.block.blocks.data(),
        sizeof(double) * static_cast<std::size_t>(b.block.blocks.size()));
    MixEdges(&h, b.edges);
    return h;
}

std::uint64_t GraphDigest(const CertifierBundle& b) {
    std::uint64_t h = 14695981039346656037ull;
    for (const auto& id : b.block.ids) Mix(&h, &id, sizeof(id));
    const Eigen::Index rank = b.block.blocks.rows();
    Mix(&h, &rank, sizeof(rank));
    MixEdges(&h, b.edges);
    return h;
}

std::uint64_t EdgesDigest(std::vector<slam::LoopClosure> edges) {
    std::sort(edges.begin(), edges.end(), [](const auto& x, const auto& y) {
        const auto key = [](const slam::LoopClosure& e) {
            const Eigen::Vector3d t = e.T_a_b.translation();
            return std::make_tuple(e.a, e.b, e.kappa, e.tau, t.x(), t.y(), t.z());
        };
        return key(x) < key(y);
    });
    std::uint64_t h = 14695981039346656037ull;
    MixEdges(&h, edges);
    return h;
}

bool AssembleBundles(const std::map<int, CertifierBundle>& bundles, std::size_t team_size,
                     slam::PoseGraph* graph, Eigen::MatrixXd* X) {
    if (bundles.size() != team_size) return false;
    // Every robot final, at one rank, its block covering its poses.
    std::map<int, int> offset;
    const int rank = static_cast<int>(bundles.begin()->second.block.blocks.rows());
    for (const auto& [robot, b] : bundles) {
        if (b.status.phase() != v1::SolverStatus::PHASE_CONVERGED) return false;
        if (b.block.blocks.rows() != rank || b.block.ids.size() != b.status.num_poses()) {
            return false;
        }
        offset[robot] = graph->n;
        for (const auto& id : b.block.ids) graph->ids.push_back(id);
        graph->n += static_cast<int>(b.block.ids.size());
    }
    X->resize(rank, 4 * graph->n);
    for (const auto& [robot, b] : bundles)
        X->middleCols(4 * offset[robot], b.block.blocks.cols()) = b.block.blocks;
    const auto index = [&](const slam::PoseId& id) -> int {
        const auto it = bundles.find(id.robot);
        if (it == bundles.end() || id.index >= int(it->second.block.ids.size())) return -1;
        return offset[id.robot] + id.index;
    };
    for (const auto& [robot, b] : bundles) {
        for (const auto& e : b.edges) {
            const int i = index(e.a), j = index(e.b);
            if (i < 0 || j < 0) return false;  // a newer bundle of the other robot is coming
            graph->edges.push_back(slam::MeasurementOf(e, i, j));
        }
    }
    return true;
}

RoundShare ShareOf(int robot, const std::map<int, const CertifierBundle*>& chosen) {
    RoundShare share;
    for (const auto& [owner, b] : chosen) {
        share.round_edges += b->edges.size();
        for (const auto& e : b->edges) {
            if (e.a.robot != robot && e.b.robot != robot) continue;
            share.edges.push_back(e);
            for (const slam::PoseId& id : {e.a, e.b}) {
                const auto it = chosen.find(id.robot);
                if (id.robot == robot || it == chosen.end()) continue;
                const auto& blocks = it->second->block.blocks;
                if (kBlock * (id.index + 1) <= blocks.cols()) {
                    share.far[id] = blocks.middleCols(kBlock * id.index, kBlock);
                }
            }
        }
    }
    return share;
}

void RememberSent(std::vector<transport::Message>* sent, transport::Message m) {
    constexpr int kReductionsKept = 2;
    if (m.Is<v1::CertificateVector>()) {
        std::erase_if(
            *sent, [](const transport::Message& old) { return old.Is<v1::CertificateVector>(); });
    } else {
        int kept = 0;
        for (auto it = sent->rbegin(); it != sent->rend(); ++it) {
            if (it->Is<v1::CertificateReduction>()) ++kept;
            if (kept == kReductionsKept) {
                sent->erase(std::next(it).base());
                break;
            }
        }
    }
    sent->push_back(std::move(m));
}

}  // namespace certislam::actors
