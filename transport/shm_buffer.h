// Buffers a producer writes in place before sealing them into an immutable SharedBuffer: in
// private memory, or in a shared-memory segment that an ipc:// Endpoint lends without a copy.
#pragma once

#include <cstddef>
#include <memory>
#include <span>

#include "transport/buffer.h"
#include "transport/shm_segment.h"

namespace certislam::transport {

/// A writable buffer, filled once by its producer and then sealed into a SharedBuffer. Move-only.
/// Get one from Endpoint::Allocate, which picks shared memory on an ipc:// edge for a large
/// size, so the producer's bytes cross to the other process without any copy.
class WritableBuffer {
  public:
    /// Private memory (uninitialised) of `size` bytes.
    static WritableBuffer Heap(std::size_t size);
    /// A new shared-memory segment of `size` bytes (pages already mapped in).
    static ShmResult<WritableBuffer> Shm(std::size_t size, const ShmConfig& config = {});

    WritableBuffer(WritableBuffer&&) noexcept = default;
    WritableBuffer& operator=(WritableBuffer&&) noexcept = default;
    ~WritableBuffer();

    /// The bytes to fill (size() long); empty after Seal.
    std::span<std::byte> bytes() { return bytes_; }
    /// Capacity in bytes.
    std::size_t size() const { return bytes_.size(); }
    /// True when the bytes lie in a shared-memory segment.
    bool in_shm() const { return segment_ != nullptr; }

    /// The first `length` bytes as an immutable SharedBuffer (no copy); the writable view is
    /// gone afterwards. Throws std::invalid_argument when length > size() or already sealed.
    SharedBuffer Seal(std::size_t length);
    /// Seal(size()).
    SharedBuffer Seal() { return Seal(size()); }

  private:
    WritableBuffer() = default;

    std::unique_ptr<std::byte[]> heap_;
    std::shared_ptr<ShmSegment> segment_;
    std::span<std::byte> bytes_;
};

}  // namespace certislam::transport
