// Internals of the shared-memory segments: the header at the start of every segment (robust
// process-shared mutex, generation, pending references, holder liveness table) and a mapping.
#pragma once

#include <pthread.h>
#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <string>

namespace certislam::transport::shm_detail {

/// Bytes before the payload (one page, so the payload can be mapped on its own read-only).
inline constexpr std::size_t kHeaderBytes = 4096;
/// Holder processes one segment tracks.
inline constexpr int kMaxHolders = 64;
/// "CSLMSHM1": written last at creation (release), so a half-made segment is never trusted.
inline constexpr std::uint64_t kMagic = 0x314d48534d4c5343ull;
/// Version of this header layout.
inline constexpr std::uint32_t kLayout = 1;

/// One holder process: pid plus its start time, so a recycled pid is not mistaken for it.
struct HolderSlot {
    std::int32_t pid = 0;  ///< 0: free
    std::uint32_t refs = 0;
    std::uint64_t start_ticks = 0;  ///< /proc/<pid>/stat field 22
};

/// The start of every segment. All fields but magic are read and written under `mutex`.
struct SegmentHeader {
    std::uint64_t magic;
    std::uint32_t layout;
    std::uint32_t unlinked;  ///< 1 once a holder unlinked the name
    pthread_mutex_t mutex;   ///< robust + process-shared: a holder dying inside it cannot wedge it
    std::uint64_t capacity;
    std::uint64_t generation;
    std::uint64_t published_offset;
    std::uint64_t published_length;
    std::int64_t loans;             ///< published references not yet taken by an Open
    std::int64_t loan_deadline_ns;  ///< CLOCK_MONOTONIC; loans are void after it
    HolderSlot holders[kMaxHolders];
};
static_assert(sizeof(SegmentHeader) <= kHeaderBytes);

/// One process's mapping of a segment: header read-write, payload read-write (writer) or
/// read-only (reader). Unmaps and closes on destruction.
struct Mapping {
    std::string name;
    int fd = -1;
    SegmentHeader* header = nullptr;
    std::byte* payload = nullptr;  ///< null when capacity == 0
    std::size_t capacity = 0;
    bool header_only = false;  ///< the payload was not mapped (reaper)

    Mapping() = default;
    Mapping(const Mapping&) = delete;
    Mapping& operator=(const Mapping&) = delete;
    ~Mapping();
};

/// Locks a header's robust mutex for a scope (recovers it when the previous owner died).
class HeaderLock {
  public:
    explicit HeaderLock(SegmentHeader* header);
    ~HeaderLock();
    HeaderLock(const HeaderLock&) = delete;
    HeaderLock& operator=(const HeaderLock&) = delete;

  private:
    SegmentHeader* header_;
};

/// Start time of a live, non-zombie process, or 0 when it is gone.
std::uint64_t ProcessStartTicks(pid_t pid);

/// Frees the slots of holders that died. Call under the lock.
void ClearDeadHolders(SegmentHeader& header);
/// Adds one reference of this process. Call under the lock. False when the table is full.
bool AddHolderRef(SegmentHeader& header);
/// Drops one reference of this process. Call under the lock.
void DropHolderRef(SegmentHeader& header);
/// References of this process now. Call under the lock.
std::uint32_t OwnRefs(const SegmentHeader& header);
/// Live holders other than this process. Call under the lock (after ClearDeadHolders).
int OtherHolders(const SegmentHeader& header);
/// True when published references are pending and not expired. Call under the lock.
bool LoansPending(const SegmentHeader& header);
/// Drops this process's reference and unlinks the name when nobody holds it any more.
void ReleaseAndMaybeUnlink(Mapping& mapping);
/// Unlinks the name when no live holder and no pending loan remain. Call under the lock.
bool UnlinkIfUnheld(Mapping& mapping);

/// CLOCK_MONOTONIC now, ns (the same clock in every process of the host).
std::int64_t MonotonicNowNs();

}  // namespace certislam::transport::shm_detail
