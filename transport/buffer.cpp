// Immutable reference-counted byte buffers and their zero-copy bridge to ZeroMQ frames.
#include "transport/buffer.h"

#include <cstring>

namespace certislam::transport {

namespace {

// zmq_msg_init_data release callback: the hint is a heap-held reference to the buffer's owner.
void ReleaseOwner(void* /*data*/, void* hint) {
    delete static_cast<std::shared_ptr<const void>*>(hint);
}

}  // namespace

SharedBuffer SharedBuffer::Adopt(std::vector<std::byte>&& bytes) {
    auto storage = std::make_shared<const std::vector<std::byte>>(std::move(bytes));
    return Wrap(storage, storage->data(), storage->size());
}

SharedBuffer SharedBuffer::Copy(const void* data, std::size_t size) {
    std::vector<std::byte> bytes(size);
    if (size > 0) std::memcpy(bytes.data(), data, size);
    return Adopt(std::move(bytes));
}

SharedBuffer SharedBuffer::Wrap(std::shared_ptr<const void> owner, const std::byte* data,
                                std::size_t size) {
    SharedBuffer buffer;
    buffer.owner_ = std::move(owner);
    buffer.data_ = data;
    buffer.size_ = size;
    return buffer;
}

SharedBuffer SharedBuffer::FromZmq(zmq::message_t&& frame) {
    auto held = std::make_shared<zmq::message_t>(std::move(frame));
    const auto* data = static_cast<const std::byte*>(held->data());
    const std::size_t size = held->size();
    return Wrap(std::move(held), data, size);
}

zmq::message_t ToZmqFrame(const SharedBuffer& buffer) {
    if (buffer.size() == 0) return zmq::message_t();
    auto* hint = new std::shared_ptr<const void>(buffer.owner());
    // ZeroMQ never writes through the pointer of a message it sends; the cast only fits its API.
    void* data = const_cast<std::byte*>(buffer.data());
    try {
        return zmq::message_t(data, buffer.size(), &ReleaseOwner, hint);
    } catch (...) {
        delete hint;
        throw;
    }
}

}  // namespace certislam::transport
