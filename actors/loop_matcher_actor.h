// Loop matcher actor: Scan Context candidates between this robot's keyframes and its own earlier
// ones or lower robots' (each pair checked once, by the higher robot, when the later of the two
// descriptors arrives: the loop set does not depend on arrival order); the lower robot's cloud
// is requested only for candidates the cloud-request gate admits (one open request per place and
// robot pair, a cloud fetched once) and travels downsampled at the registration voxel; GICP seeded
// by the Scan Context yaw verifies (on a pool of worker threads, each verdict applied in the order
// the candidates came, as one thread would); verified loops pass pairwise
// consistency maximisation (re-evaluated on each new loop: a loop that drops out of the consistent
// set is withdrawn) and go to both robots' solvers.
#pragma once

#include <atomic>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <deque>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "actors/node_actor.h"
#include "actors/streams.h"
#include "certislam/v1/loop_closure.pb.h"
#include "slam/core/loop_closure.h"
#include "slam/frontend/cloud_request_gate.h"
#include "slam/frontend/incremental_pcm.h"
#include "slam/frontend/pcm.h"
#include "slam/frontend/registration.h"
#include "slam/frontend/scan_context.h"

namespace certislam::actors {

/// Settings of the loop matcher.
struct LoopMatcherConfig {
    double max_sc_distance = 0.2;  ///< Scan Context distance accepting a candidate, (0, 1]
    int query_stride = 3;          ///< only keyframes with index % stride == 0 take part, >= 1
    int min_intra_gap = 40;        ///< keyframes between an intra-robot pair, >= 1
    bool intra_robot = true;       ///< also close loops within the robot
    double max_rmse_m = 0.3;       ///< registration inlier RMSE accepting a loop, > 0
    bool reject_outliers = true;   ///< PCM over the verified loops before they are sent
    /// Consistency test and clique search; the search runs after every verified batch, so its
    /// budget is a tenth of the batch PCM's (the best clique so far is kept, Exact() false).
    slam::PcmConfig pcm = [] {
        slam::PcmConfig c;
        c.max_branch_nodes = 5'000'000;
        return c;
    }();
    slam::RegistrationConfig registration;          ///< verification
    std::chrono::milliseconds request_retry{1000};  ///< cloud requests re-sent after this, > 0
    /// Keyframes that make one place for the cloud-request gate (slam/cloud_request_gate.h),
    /// >= 0: an inter-robot candidate within this window of an admitted one on both robots is
    /// skipped. 0: every candidate is verified (each peer cloud is still fetched only once).
    int place_window = 0;
    /// Own keyframe clouds kept and sent in cloud replies downsampled at registration.voxel_m
    /// (else at full resolution).
    bool downsample_replies = true;
    /// Candidates registered per own keyframe and robot it is matched against, >= 0: the best
    /// by Scan Context distance among the descriptors at hand (0: every candidate). In a
    /// featureless place (a tunnel) one keyframe resembles a whole stretch of the other's.
    int max_candidates_per_query = 0;
    /// Keyframes whose clouds stay prepared for registration (downsampled, trees, GICP
    /// covariances), >= 0, the latest used kept: a keyframe is often in several candidates.
    int prepared_clouds = 16;
    /// Worker threads running the registrations, >= 1. Verdicts are applied in candidate order
    /// whatever the threads' timing; with place_window > 0 the gate waits for every verdict
    /// before admitting the next inter-robot candidate, as it needs them (so inter-robot
    /// candidates then register one at a time).
    int registration_threads = 2;

    /// Throws std::invalid_argument naming the field, its value and the rule it breaks.
    void Validate() const;
};

/// Scan Context + registration loop closures, inter-robot cloud exchange on request.
class LoopMatcherActor final : public NodeActor {
  public:
    LoopMatcherActor(zmq::context_t& context, TeamWiring wiring, LoopMatcherConfig config);
    ~LoopMatcherActor() override { Stop(); }

    /// Loops accepted now (sent and not withdrawn).
    int LoopsFound() const { return loops_.load(); }
    /// Candidates registration rejected so far.
    int Rejected() const { return rejected_.load(); }
    /// Loops registration verified so far (PCM's input).
    int Verified() const { return verified_.load(); }
    /// Withdrawals sent so far (loops that dropped out of the consistent set).
    int Withdrawn() const { return withdrawn_.load(); }
    /// Inter-robot candidates the cloud-request gate skipped so far.
    int Skipped() const { return skipped_.load(); }
    /// Candidates left out by max_candidates_per_query so far.
    int Capped() const { return capped_.load(); }
    /// Peer clouds requested so far (distinct keyframes; retries not counted).
    int CloudsRequested() const { return clouds_requested_.load(); }
    /// True once the end-of-loops marker went out.
    bool Ended() const { return ended_.load(); }

  protected:
    void OnStart() override;
    void OnStop() override;

  private:
    struct Pending {
        slam::LoopCandidate candidate;  ///< query: own keyframe; match: the cloud's keyframe
        std::chrono::steady_clock::time_point sent;
    };
    /// A cloud prepared for registration by the first worker that needs it (others wait).
    class LazyPrepared {
      public:
        LazyPrepared(slam::PointCloudPtr cloud, const slam::RegistrationConfig& config,
                     bool as_target)
            : cloud_(std::move(cloud)), config_(config), as_target_(as_target) {}
        const slam::PreparedCloud& Get();
        /// True when prepared (or to be) as a target: it serves as a source as well.
        bool as_target() const { return as_target_; }

      private:
        std::once_flag once_;
        slam::PointCloudPtr cloud_;  ///< released once prepared
        slam::RegistrationConfig config_;
        bool as_target_ = true;
        std::unique_ptr<const slam::PreparedCloud> prepared_;
    };
    struct Registration {  ///< a candidate on the workers
        slam::LoopCandidate candidate;
        std::future<slam::RegistrationResult> result;
    };

    bool OnDescriptor(const transport::Message& m);
    bool OnCloudRequest(const transport::Message& m);
    bool OnCloudReply(const transport::Message& m);
    void Consider(const slam::LoopCandidate& candidate);
    /// Queues the candidate's registration on the workers.
    void Verify(const slam::LoopCandidate& candidate, const slam::PointCloudPtr& match_cloud);
    /// Applies finished registrations in queue order up to the first unfinished one, then waits
    /// for the head until at most `at_most` are left queued.
    void ApplyRegistrations(std::size_t at_most);
    void Apply(const slam::LoopCandidate& candidate, const slam::RegistrationResult& result);
    /// `cloud` of keyframe `id` to be prepared for registration (`as_target`: as a candidate's
    /// target, which a source-only preparation cannot serve), kept among the latest used.
    std::shared_ptr<LazyPrepared> Prepared(const slam::PoseId& id, const slam::PointCloudPtr& cloud,
                                           bool as_target);
    void RequestCloud(std::uint64_t id, const Pending& p);
    slam::PointCloudPtr ReplyCloud(int index);
    void OnOwnKeyframe(const slam::Keyframe& keyframe);
    void SendLoop(v1::LoopClosure proto, bool inter_robot);
    void Reconcile();
    void Tick();
    /// True once robot r's end-of-descriptors marker came and every descriptor it counted is in
    /// (a marker can overtake descriptors re-sent to a late subscriber).
    bool StreamEnded(int r) const;

    LoopMatcherConfig config_;
    transport::Endpoint* loops_out_ = nullptr;
    transport::Endpoint* clouds_server_ = nullptr;
    std::map<int, transport::Endpoint*> cloud_clients_;  ///< lower robot -> dealer
    std::map<int, slam::PointCloudPtr> own_clouds_;      ///< own keyframe -> cloud (as kept, sent)
    std::map<slam::PoseId, slam::PointCloudPtr> peer_clouds_;  ///< fetched, kept (gate: once)
    std::map<slam::PoseId, std::vector<slam::LoopCandidate>> waiting_;  ///< on a fetch
    std::map<slam::PoseId, std::shared_ptr<LazyPrepared>> prepared_;
    std::deque<slam::PoseId> prepared_order_;  ///< prepared_'s keys, least recently used first
    slam::CloudRequestGate gate_;
    std::unique_ptr<boost::asio::thread_pool> workers_;             ///< while running
    std::deque<Registration> registrations_;                        ///< queued, in candidate order
    std::map<slam::PoseId, slam::ScanContextColumns> descriptors_;  ///< own and lower robots'
    std::map<std::uint64_t, Pending> pending_;  ///< request id -> candidate that fetched
    std::vector<Pending> deferred_;          ///< own clouds not yet arrived (descriptor came first)
    std::map<int, std::set<int>> received_;  ///< robot -> keyframe indices described to us
    std::map<int, std::uint64_t> end_counts_;  ///< robot -> descriptors its end marker counted
    std::uint64_t next_request_ = 0;
    std::map<int, slam::KeyframeOdometry> own_odometry_;  ///< own keyframe -> odometry
    std::map<std::pair<int, int>, int> considered_;       ///< (own keyframe, robot) -> candidates
    slam::IncrementalPcm pcm_;
    bool pcm_dirty_ = false;  ///< a loop was verified since the last Reconcile()
    std::map<std::pair<slam::PoseId, slam::PoseId>, slam::LoopClosure> sent_;  ///< accepted now
    std::int64_t last_version_ = 0;
    std::size_t seen_subscribers_ = 0;  ///< subscribers of loops_out_ at the last tick
    std::atomic<int> loops_{0};
    std::atomic<int> rejected_{0};
    std::atomic<int> verified_{0};
    std::atomic<int> withdrawn_{0};
    std::atomic<int> skipped_{0};
    std::atomic<int> capped_{0};
    std::atomic<int> clouds_requested_{0};
    std::atomic<bool> ended_{false};
};

}  // namespace certislam::actors
