// Immutable reference-counted byte buffers: the zero-copy unit of large payloads.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <vector>
#include <zmq.hpp>

namespace certislam::transport {

class ShmSegment;

/// An immutable, reference-counted byte buffer. Copies of a SharedBuffer share the bytes.
/// Sent over inproc it travels as a handle (zmq_msg_init_data with a release callback), so the
/// receiver's data() is the sender's data(); the bytes are freed when the last holder, on either
/// side of the socket, lets go.
class SharedBuffer {
  public:
    /// An empty buffer (size 0, data() may be null).
    SharedBuffer() = default;

    /// Takes ownership of the bytes (no copy).
    static SharedBuffer Adopt(std::vector<std::byte>&& bytes);

    /// Copies size bytes from data into a new buffer.
    static SharedBuffer Copy(const void* data, std::size_t size);

    /// Wraps bytes owned by any shared owner; data must stay valid and unchanged while owner lives.
    static SharedBuffer Wrap(std::shared_ptr<const void> owner, const std::byte* data,
                             std::size_t size);

    /// Takes a received ZeroMQ frame without copying it (keeps the frame alive).
    static SharedBuffer FromZmq(zmq::message_t&& frame);

    /// First byte (null when empty).
    const std::byte* data() const { return data_; }
    /// Length in bytes.
    std::size_t size() const { return size_; }
    /// The bytes as a span.
    std::span<const std::byte> span() const { return {data_, size_}; }
    /// Number of holders of the underlying storage (this buffer's copies, zmq messages in flight).
    long use_count() const { return owner_.use_count(); }
    /// A weak reference to the storage: expired() once every holder has released it.
    std::weak_ptr<const void> Watch() const { return owner_; }
    /// The storage owner (for handing the buffer to other zero-copy APIs).
    const std::shared_ptr<const void>& owner() const { return owner_; }

    /// The bytes [0, size) of a shared-memory segment this process wrote and sealed (see
    /// WritableBuffer in transport/shm_buffer.h): an ipc:// Endpoint lends them to the reader
    /// process without a copy. The segment must not be written any more.
    static SharedBuffer InShm(std::shared_ptr<ShmSegment> segment, std::size_t size);
    /// The segment holding the bytes when the buffer was made by InShm, else null.
    const std::shared_ptr<ShmSegment>& shm_segment() const { return shm_segment_; }

  private:
    std::shared_ptr<const void> owner_;
    std::shared_ptr<ShmSegment> shm_segment_;
    const std::byte* data_ = nullptr;
    std::size_t size_ = 0;
};

/// Builds a ZeroMQ frame that points at the buffer's bytes (no copy): the frame holds a
/// reference to the buffer until ZeroMQ releases it (zmq_msg_init_data + release callback).
zmq::message_t ToZmqFrame(const SharedBuffer& buffer);

}  // namespace certislam::transport
