// TeamFinish's Steihaug-CG iterations (team_finish_impl.h): the preconditioner's exchanges
// and sums, the curvature, the step to the trust region's boundary.
#include "certify/pipeline/team_finish_impl.h"
#include "slam/backend/stiefel.h"

namespace certislam::certify {

using finish_detail::Inner;
using finish_detail::kD;

// z = Proj(P^{-1} r): block Jacobi locally; with overlap, the domain's solve, after a gather of
// the neighbours' r on the own domain at a step's first CG iteration (later ones update it).
void TeamFinish::Impl::StartPrecondition() {
    if (config.overlap == 0) {
        z = slam::ProjectToTangent(at.X, domain.Solve(r), kD);
        SendSums({Inner(r, z), r.squaredNorm()});
        phase = Phase::kPrecSums;
        return;
    }
    SendDomainEntries(r);
    phase = Phase::kGather;
}

bool TeamFinish::Impl::Gathered() {
    auto* in = Received();
    if (in == nullptr) return false;
    r_nbr.clear();
    StoreEntries(*in, &r_nbr);
    vectors.erase(exchange - 1);
    SolveDomain();
    return true;
}

// The domain's solve of r: the neighbours' shares go back (scatter) while the domain's own term
// of <r, z> = sum over domains D of <r_D, A_D^{-1} r_D> (r is tangent) goes into the sums.
void TeamFinish::Impl::SolveDomain() {
    std::map<int, std::vector<slam::PoseId>> ids;
    std::map<int, Eigen::MatrixXd> blocks;
    for (int j : neighbours) ids[j];
    double rz_domain = 0.0;
    if (!domain.Solve(r, r_nbr, &z, &ids, &blocks, &rz_domain)) {
        Spoil();
        z = Eigen::MatrixXd::Zero(r.rows(), r.cols());
        ids.clear();
        for (int j : neighbours) blocks[j] = Eigen::MatrixXd(r.rows(), 0);  // an empty scatter
    }
    SendEach(blocks, ids);
    SendSums({rz_domain, r.squaredNorm()});
    phase = Phase::kScatter;
}

bool TeamFinish::Impl::ApplyScatter() {
    auto* in = Received();
    if (in == nullptr) return false;
    std::vector<double> s;
    if (!Reduced(2, &s)) return false;
    if (!domain.AddReturned(*in, &z)) Spoil();
    vectors.erase(exchange - 1);
    z = slam::ProjectToTangent(at.X, z, kD);
    OnPrecSums(s);
    return true;
}

void TeamFinish::Impl::OnPrecSums(const std::vector<double>& s) {
    const double rz_new = s[0];
    const double r_norm = std::sqrt(std::max(s[1], 0.0));
    if (initial_prec) {
        initial_prec = false;
        if (radius < 0.0) {  // the preconditioned gradient's size, about the Newton step's
            radius = std::sqrt(std::max(rz_new, 0.0));
            max_radius = 1e3 * std::max(radius, 1e-12);
        }
        stop = std::max(r_norm * std::min(r_norm, 0.1), config.tcg_residual_floor * tol);
        rz = rz_new;
        delta = -z;
        e_Pe = e_Pd = 0.0;
        d_Pd = rz;
    } else {
        if (r_norm <= stop || tcg >= config.max_tcg_iterations) return EndTcg();
        const double beta = rz_new / rz;
        rz = rz_new;
        delta = -z + beta * delta;
        e_Pd = beta * (e_Pd + alpha * d_Pd);
        d_Pd = rz + beta * beta * d_Pd;
    }
    SendRead(delta, false);
    phase = Phase::kProduct;
}

void TeamFinish::Impl::OnCurvSums(double dHd,
                                  const std::map<slam::PoseId, Eigen::MatrixXd>& hd_nbr) {
    ++tcg;
    ++progress.tcg_iterations;
    alpha = rz / dHd;
    const double e_Pe_new = e_Pe + 2.0 * alpha * e_Pd + alpha * alpha * d_Pd;
    if (dHd <= 0.0 || e_Pe_new >= radius * radius) {  // to the boundary along delta
        const double tau = SteihaugToBoundary(e_Pe, e_Pd, d_Pd, radius);
        eta += tau * delta;
        Heta += tau * Hd;
        hit_boundary_ = true;
        return EndTcg();
    }
    e_Pe = e_Pe_new;
    eta += alpha * delta;
    Heta += alpha * Hd;
    r = slam::ProjectToTangent(at.X, r + alpha * Hd, kD);
    if (config.overlap == 0) return StartPrecondition();
    // The neighbours' r on the own domain as they update it (tangent plus tangent: no projection;
    // they project their own to remove rounding, a difference far below CG's tolerance).
    for (auto& [id, block] : r_nbr) {
        const auto it = hd_nbr.find(id);
        if (it == hd_nbr.end() || it->second.rows() != block.rows()) {
            Spoil();
            continue;
        }
        block += alpha * it->second;
    }
    SolveDomain();
}

void TeamFinish::Impl::EndTcg() {
    cand = FinishPoint{};
    cand.X = slam::Retract(at.X, eta, kD);
    SendRead(cand.X, true);
    phase = Phase::kCandidate;
}

}  // namespace certislam::certify
