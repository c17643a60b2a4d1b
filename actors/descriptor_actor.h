// Descriptor actor: Scan Context of each keyframe, published to the robot's loop matcher and to
// its peers' (about 5 KB each instead of the cloud); forwards the end-of-stream marker.
#pragma once

#include <set>
#include <vector>

#include "actors/node_actor.h"
#include "actors/streams.h"
#include "slam/frontend/scan_context.h"

namespace certislam::actors {

/// Keyframe -> ScanContextDescriptor.
class DescriptorActor final : public NodeActor {
  public:
    DescriptorActor(zmq::context_t& context, TeamWiring wiring, slam::ScanContextConfig config);
    ~DescriptorActor() override { Stop(); }

  protected:
    void OnStart() override;
    void OnStop() override { CloseEndpoints(); }

  private:
    void SendEnd();
    void Resync();

    slam::ScanContextConfig config_;
    transport::Endpoint* out_ = nullptr;
    bool ended_ = false;
    std::vector<transport::Message> sent_;  ///< every descriptor published, for rejoining peers
    std::set<int> described_;               ///< keyframe indices in sent_ (each described once)
    std::size_t seen_subscribers_ = 0;
};

}  // namespace certislam::actors
