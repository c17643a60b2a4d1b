// A local search's result (LM on the geodesic cost) judged on the certificate's objective f:
// polished by a few Riemannian trust-region steps at rank d, then certified or refused
// (MATH.md, "What a report may claim": LM stops critical for its own cost, not for f).
#pragma once

#include "certify/certificate.h"
#include "slam/backend/rbcd.h"
#include "slam/core/pose_graph.h"

namespace certislam::certify {

/// Settings of CertifyLocalSearch.
struct LocalSearchPolishConfig {
    /// The polish: RBCD with the whole graph as one block (a Riemannian trust region on f) at
    /// rank d, stopping at its own relative gradient tolerance, well below the certificate's.
    slam::RbcdConfig rbcd = [] {
        slam::RbcdConfig c;
        c.max_iterations = 50;
        return c;
    }();
    CertificateConfig certificate;  ///< the verdict on the polished poses

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// The polished poses and their certificate.
struct LocalSearchCertificate {
    slam::PoseMatrix poses;         ///< d x (d+1)n, the polished estimate (the certified X itself)
    double input_cost = 0.0;        ///< f at the local search's poses
    int polish_iterations = 0;      ///< RBCD iterations of the polish
    CertificateResult certificate;  ///< of `poses`; its objective is f(poses)
};

/// Polishes `poses` (d x (d+1)n, rotations in SO(d)) on f and certifies the result.
LocalSearchCertificate CertifyLocalSearch(const slam::PoseGraph& graph,
                                          const slam::PoseMatrix& poses,
                                          const LocalSearchPolishConfig& config = {});

}  // namespace certislam::certify
