// The distributed LOBPCG over plain data: a team of LobpcgParticipants run in memory.
#include "certify/distributed/distributed_lobpcg.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "certify/distributed/distributed_lanczos.h"
#include "certify/distributed/lobpcg_participant.h"
#include "slam/core/check.h"

namespace certislam::certify {

void LobpcgSettings::Validate() const {
    const auto fail = [](const std::string& field, double value, const std::string& rule) {
        throw std::invalid_argument("LobpcgSettings." + field + " = " + std::to_string(value) +
                                    ": must be " + rule);
    };
    if (block_size < 1 || block_size > kMaxBlockSize) {
        fail("block_size", block_size, "in [1, 16]");
    }
    if (max_iterations < 1) fail("max_iterations", max_iterations, ">= 1");
    if (!(tolerance > 0.0)) fail("tolerance", tolerance, "> 0");
    if (!(shift_relative > 0.0)) fail("shift_relative", shift_relative, "> 0");
    if (!(shift_growth > 1.0)) fail("shift_growth", shift_growth, "> 1");
    if (!(drop_tolerance > 0.0 && drop_tolerance < 1.0)) {
        fail("drop_tolerance", drop_tolerance, "in (0, 1)");
    }
}

LobpcgResult DistributedLobpcg(const std::vector<CertificateRows>& robots,
                               const LobpcgSettings& settings) {
    settings.Validate();
    CERTISLAM_CHECK(!robots.empty());
    LanczosSettings round;
    round.method = LanczosSettings::Method::kLobpcg;
    round.lobpcg = settings;
    InMemoryTraffic traffic;
    const auto team = RunInMemory(LocalProblemsOf(robots), round, &traffic);
    const auto* first = dynamic_cast<const LobpcgParticipant*>(team.front().get());
    CERTISLAM_CHECK(first != nullptr && first->Done());
    const DistributedVerdict& verdict = first->Verdict();
    CERTISLAM_CHECK(verdict.status != DistributedVerdict::Status::kInconsistent);
    LobpcgResult result;
    result.status = verdict.status == DistributedVerdict::Status::kConverged
                        ? LobpcgResult::Status::kConverged
                        : LobpcgResult::Status::kNotConverged;
    result.lambda_min = verdict.lambda_min;
    result.residual = verdict.residual_estimate;
    const LobpcgProgress& p = first->Progress();
    result.scale = p.scale;
    result.iterations = p.iterations;
    result.products = p.products;
    result.vector_exchanges = p.exchanges;
    result.scalar_reductions = p.reductions;
    result.scalars_reduced = p.scalars_reduced;
    result.entries_exchanged = traffic.entries;
    result.restarts = p.restarts;
    for (const auto& r : team) {
        result.vector.push_back(r->RitzSegment());
        const auto* participant = dynamic_cast<const LobpcgParticipant*>(r.get());
        result.max_shift = std::max(result.max_shift, participant->Progress().shift);
    }
    return result;
}

}  // namespace certislam::certify
