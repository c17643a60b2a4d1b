// The shared-memory path of an ipc:// edge: the sending Endpoint turns large inline frames into
// descriptors of segments (lent without a copy when the producer wrote in shared memory, else
// copied into a pooled, pre-faulted segment); the receiving Endpoint maps them back into frames.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "transport/message.h"
#include "transport/shm_segment.h"

namespace certislam::transport {

/// What one ShmLender::Lend did (added to the endpoint's counters).
struct ShmLendStats {
    std::uint64_t lent = 0;      ///< frames lent from the producer's own segment (no copy)
    std::uint64_t copied = 0;    ///< frames copied into a pooled segment
    std::uint64_t copy_ns = 0;   ///< time spent in those copies
    std::uint64_t fallback = 0;  ///< frames left inline because no segment could be made
};

/// The references one message lent; Revoke() takes them back when the send failed.
class ShmLoans {
  public:
    /// Records `readers` references lent from segment.
    void Add(std::shared_ptr<ShmSegment> segment, int readers);
    /// Takes every recorded reference back (the descriptors never left the process).
    void Revoke();

  private:
    std::vector<std::pair<std::shared_ptr<ShmSegment>, int>> loans_;
};

/// Sender side. One thread uses it at a time (the endpoint's).
class ShmLender {
  public:
    /// Reaps this family's segments left by dead processes, then keeps up to `pool_segments`
    /// segments for copies. Frames of at least `threshold_bytes` go through shared memory.
    ShmLender(ShmConfig config, std::size_t threshold_bytes, std::size_t pool_segments);

    /// True when the message has an inline frame of at least the threshold.
    bool Wants(const Message& message) const;

    /// Replaces each large inline frame of `wire` by a descriptor lent to `readers` opens
    /// (readers >= 1); records the loans in `loans` and what it did in `stats`.
    void Lend(Message& wire, int readers, ShmLoans& loans, ShmLendStats& stats);

  private:
    std::shared_ptr<ShmSegment> Take(std::size_t bytes);
    void MaybeReap();

    ShmConfig config_;
    std::size_t threshold_;
    std::size_t pool_limit_;
    std::vector<std::shared_ptr<ShmSegment>> pool_;
    std::int64_t next_reap_ns_ = 0;
};

/// Receiver side: maps descriptor frames back into inline frames that point into the mapping.
class ShmResolver {
  public:
    /// Validates the config.
    explicit ShmResolver(ShmConfig config);

    /// Replaces every descriptor frame of `message` by a SharedBuffer backed by the read-only
    /// mapping (released, and the segment reclaimed by its last holder, when the last copy of
    /// the buffer goes). False (with a reason in detail) on a malformed or forged descriptor,
    /// or one whose segment is gone; the message must then be dropped. Never throws on bytes.
    bool Resolve(Message& message, std::string& detail);

  private:
    ShmReader reader_;
};

/// True when the message has at least one descriptor frame.
bool HasShmFrames(const Message& message);

}  // namespace certislam::transport
