// Certifier actor: the team anchor's certifier (lowest robot id) assembles the converged blocks
// and edges the solvers hand over, checks the dual certificate (lambda_min of S), reports the
// verdict to every robot, and when it is a saddle sends each robot its block at rank r+1
// (Riemannian staircase). The other robots' certifiers listen to the verdict.
#pragma once

#include <atomic>
#include <chrono>
#include <map>
#include <optional>
#include <vector>

#include "actors/codec.h"
#include "actors/node_actor.h"
#include "certify/certificate.h"
#include "certislam/v1/rbcd.pb.h"

namespace certislam::actors {

/// Settings of the certifier actor.
struct CertifierConfig {
    certify::CertificateConfig certificate;  ///< the check
    int max_staircase_steps = 3;             ///< saddle escapes at most, >= 0
    std::chrono::milliseconds period{200};   ///< checks at most this often, > 0

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Distributed-solution certifier (centralised check at the anchor robot).
class CertifierActor final : public NodeActor {
  public:
    CertifierActor(zmq::context_t& context, TeamWiring wiring, CertifierConfig config);
    ~CertifierActor() override { Stop(); }

    /// Certificates computed here so far.
    int Checks() const { return checks_.load(); }
    /// Saddle escapes sent so far.
    int Escapes() const { return escapes_.load(); }

  protected:
    void OnStart() override;
    void OnStop() override { CloseEndpoints(); }

  private:
    struct Bundle {
        v1::SolverStatus status;
        std::vector<slam::LoopClosure> edges;
        PoseBlocks block;
    };
    void Tick();
    void Escape(const Eigen::SparseMatrix<double>& Q, const Eigen::MatrixXd& X,
                const Eigen::VectorXd& v, double gradient_tolerance);

    CertifierConfig config_;
    bool anchor_ = false;
    transport::Endpoint* out_ = nullptr;
    std::map<int, Bundle> pending_;  ///< bundles being received
    std::map<int, Bundle> bundles_;  ///< last complete bundle per robot
    bool dirty_ = false;
    int level_ = 0;
    std::atomic<int> checks_{0};
    std::atomic<int> escapes_{0};
};

}  // namespace certislam::actors
