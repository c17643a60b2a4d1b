// The decoders of the solver status and of the distributed certificate round's messages
// (actors/convert.h): peers' bytes checked before a solver or a Lanczos participant sees them.
#include <climits>
#include <cmath>
#include <set>

#include "actors/convert.h"
#include "certify/distributed/distributed_lobpcg.h"

namespace certislam::actors {
namespace {

constexpr std::uint32_t kMaxRank = 64;  ///< the largest relaxation rank PublicPoses carries

bool FitsInt(std::uint64_t v) { return v <= static_cast<std::uint64_t>(INT_MAX); }

bool AllFinite(const auto& values) {
    for (const double v : values) {
        if (!std::isfinite(v)) return false;
    }
    return true;
}

}  // namespace

bool IsValidStatus(const v1::SolverStatus& status) {
    return FitsInt(status.header().robot_id()) && FitsInt(status.staircase_level()) &&
           status.rank_r() <= kMaxRank && std::isfinite(status.cost()) &&
           std::isfinite(status.gradient_norm());
}

bool IsValidRound(const v1::CertificateRound& round) {
    if (round.round() == 0 || round.rank_r() < 3 || round.rank_r() > kMaxRank) return false;
    std::set<std::uint32_t> robots;
    for (const auto& ref : round.bundles()) {
        if (!FitsInt(ref.robot_id()) || !robots.insert(ref.robot_id()).second) return false;
        for (const auto n : ref.neighbors()) {
            if (!FitsInt(n)) return false;
        }
    }
    return true;
}

std::optional<RoundVector> FromProto(const v1::CertificateVector& vector) {
    const auto count = static_cast<std::size_t>(vector.pose_ids_size());
    // One vector (Lanczos) or a block of up to certify::kMaxBlockSize columns (LOBPCG).
    const std::size_t per_column = count * kCertificateBlock;
    const auto values = static_cast<std::size_t>(vector.values_size());
    const bool shape = per_column == 0 ? values == 0
                                       : values % per_column == 0 && values >= per_column &&
                                             values / per_column <= certify::kMaxBlockSize;
    if (vector.round() == 0 || vector.block_size() != kCertificateBlock || !shape ||
        !FitsInt(vector.header().robot_id()) || !FitsInt(vector.step()) ||
        !AllFinite(vector.values())) {
        return std::nullopt;
    }
    RoundVector out;
    out.round = vector.round();
    out.robot = static_cast<int>(vector.header().robot_id());
    out.step = static_cast<int>(vector.step());
    for (const auto& id : vector.pose_ids()) {
        const auto pose = FromProto(id);
        if (!pose) return std::nullopt;
        out.ids.push_back(*pose);
    }
    out.values = Eigen::Map<const Eigen::VectorXd>(vector.values().data(),
                                                   static_cast<Eigen::Index>(vector.values_size()));
    return out;
}

std::optional<RoundReduction> FromProto(const v1::CertificateReduction& reduction) {
    if (reduction.round() == 0 || !FitsInt(reduction.header().robot_id()) ||
        !FitsInt(reduction.step()) || !FitsInt(reduction.stage()) ||
        !AllFinite(reduction.values())) {
        return std::nullopt;
    }
    return RoundReduction{reduction.round(),
                          static_cast<int>(reduction.header().robot_id()),
                          static_cast<int>(reduction.step()),
                          static_cast<int>(reduction.stage()),
                          {reduction.values().begin(), reduction.values().end()}};
}

}  // namespace certislam::actors
