// Same-host shared-memory buffers: a large buffer is written once into a POSIX shm segment and
// only a small descriptor travels on the socket; the receiver maps it read-only. A segment is
// unlinked when its last holder releases it, and also when its holders died (liveness records).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "certislam/v1/envelope.pb.h"

namespace certislam::transport {

/// Settings shared by writers, readers and the reaper of one family of segments.
struct ShmConfig {
    /// Segment names are "/<prefix>-<pid>-<n>-<random>"; 1-32 characters of [A-Za-z0-9_].
    std::string prefix = "certislam";
    /// A published descriptor not opened within this is void (its reader probably died).
    std::chrono::milliseconds loan_ttl{30000};
    /// Largest segment a writer creates, bytes.
    std::size_t max_segment_bytes = std::size_t{8} << 30;

    /// Throws std::invalid_argument naming the field, value and rule.
    void Validate() const;
};

/// What travels on the socket instead of the bytes (see v1::ShmDescriptor).
struct ShmDescriptor {
    std::string segment_name;        ///< POSIX shm name, "/<prefix>-..."
    std::uint64_t offset_bytes = 0;  ///< start of the buffer inside the segment's payload
    std::uint64_t byte_length = 0;   ///< length of the buffer
    std::uint64_t generation = 0;    ///< the segment's generation when it was published
};

/// The descriptor as its protobuf message (header left unset).
v1::ShmDescriptor ToProto(const ShmDescriptor& descriptor);
/// The protobuf message as a descriptor (not validated: ShmReader::Open validates).
ShmDescriptor FromProto(const v1::ShmDescriptor& message);

/// Every way opening or creating a segment can end.
enum class ShmStatus {
    kOk,
    kBadName,          ///< not a name of this prefix's family (forged or corrupt descriptor)
    kNotFound,         ///< no such segment (already reclaimed, or never existed)
    kBadSegment,       ///< exists but is not an initialised certislam segment
    kStaleGeneration,  ///< the segment was republished since the descriptor was made
    kOutOfRange,       ///< offset/length outside the published bytes
    kNoLoan,           ///< every reference the writer published was already taken
    kLoanExpired,      ///< published longer than loan_ttl ago
    kHoldersFull,      ///< the segment's table of holder processes is full
    kSystemError,      ///< a system call failed (detail says which)
};

/// Short name of a status ("ok", "bad-name", ...).
const char* ToString(ShmStatus status);

/// A status with a value when it is kOk.
template <class T>
struct ShmResult {
    ShmStatus status = ShmStatus::kOk;
    std::string detail;      ///< human-readable reason when not kOk
    std::optional<T> value;  ///< set when status == kOk
    bool ok() const { return status == ShmStatus::kOk; }
};

namespace shm_detail {
struct Mapping;
}

/// Writer side: one segment mapped writable; this process is a holder while it lives.
/// Write into writable(), then Publish() and send the descriptor. Before writing again, check
/// Reusable() (no reader holds the bytes and no published reference is pending).
class ShmSegment {
  public:
    /// Creates a segment of `capacity` payload bytes.
    static ShmResult<ShmSegment> Create(std::size_t capacity, const ShmConfig& config = {});

    ShmSegment(ShmSegment&&) noexcept = default;
    ShmSegment& operator=(ShmSegment&&) noexcept;
    ~ShmSegment();

    /// The payload bytes, writable (capacity() long).
    std::span<std::byte> writable();
    /// Payload capacity in bytes.
    std::size_t capacity() const;
    /// The POSIX shm name.
    const std::string& name() const;

    /// Starts a new generation (old descriptors become stale) that publishes
    /// [offset, offset + length) for `readers` opens within loan_ttl. Throws
    /// std::invalid_argument when the range exceeds the capacity or readers < 1.
    ShmDescriptor Publish(std::size_t length, int readers = 1, std::size_t offset = 0);

    /// Lends the immutable bytes [0, length) to `readers` more opens within loan_ttl without
    /// changing them: the generation is kept while the published range stays [0, length), so
    /// descriptors lent earlier stay valid (a sealed buffer sent on several edges). Throws
    /// std::invalid_argument when length exceeds the capacity or readers < 1.
    ShmDescriptor Lend(std::size_t length, int readers);

    /// Takes back up to `readers` pending references (their descriptors were never sent).
    void Unlend(int readers);

    /// True when the bytes may be overwritten: no other live holder, and no pending reference.
    bool Reusable();

  private:
    ShmSegment(std::shared_ptr<shm_detail::Mapping> mapping, ShmConfig config);
    void Release();

    std::shared_ptr<shm_detail::Mapping> mapping_;
    ShmConfig config_;
};

/// Reader side: a read-only view of one published buffer; this process holds the segment until
/// the view is destroyed (the last holder to go unlinks it).
class ShmView {
  public:
    ShmView(ShmView&&) noexcept = default;
    ShmView& operator=(ShmView&&) noexcept;
    ~ShmView();

    /// The buffer's bytes (read-only mapping: writing through them faults).
    std::span<const std::byte> bytes() const { return bytes_; }

  private:
    friend class ShmReader;
    ShmView(std::shared_ptr<shm_detail::Mapping> mapping, std::span<const std::byte> bytes);
    void Release();

    std::shared_ptr<shm_detail::Mapping> mapping_;
    std::span<const std::byte> bytes_;
};

/// Opens descriptors received from other processes. Keeps recently used mappings so a segment a
/// writer reuses is not mapped again. One thread uses a reader at a time.
class ShmReader {
  public:
    /// Validates the config.
    explicit ShmReader(ShmConfig config = {});

    /// Validates the descriptor against the segment and takes one published reference.
    /// Never throws on a bad descriptor: the status says what was wrong.
    ShmResult<ShmView> Open(const ShmDescriptor& descriptor);

    /// Mappings kept for reuse now.
    std::size_t cached() const { return cache_.size(); }

  private:
    ShmResult<std::shared_ptr<shm_detail::Mapping>> MappingFor(const std::string& name);
    void Trim();

    ShmConfig config_;
    std::map<std::string, std::shared_ptr<shm_detail::Mapping>> cache_;
};

/// Unlinks this family's segments whose holders are all dead (or gone) and that have no
/// unexpired published reference; returns how many it unlinked. Safe to run at any time from
/// any process (e.g. on a timer, and at start-up after a crash).
std::size_t ReapShmSegments(const ShmConfig& config = {});

/// True when a segment of that name exists now (shm_open succeeds).
bool ShmSegmentExists(const std::string& name);

}  // namespace certislam::transport
