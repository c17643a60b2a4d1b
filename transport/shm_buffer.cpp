// Writable buffers sealed into SharedBuffers, in private or shared memory.
#include "transport/shm_buffer.h"

#include <stdexcept>
#include <string>
#include <utility>

namespace certislam::transport {

SharedBuffer SharedBuffer::InShm(std::shared_ptr<ShmSegment> segment, std::size_t size) {
    if (segment == nullptr || size > segment->capacity()) {
        throw std::invalid_argument("SharedBuffer::InShm: size " + std::to_string(size) +
                                    " exceeds the segment");
    }
    const std::byte* data = segment->writable().data();
    SharedBuffer buffer = Wrap(segment, data, size);
    buffer.shm_segment_ = std::move(segment);
    return buffer;
}

WritableBuffer WritableBuffer::Heap(std::size_t size) {
    WritableBuffer buffer;
    // Default-initialised: the producer overwrites every byte, so zeroing would be wasted.
    buffer.heap_ = std::make_unique_for_overwrite<std::byte[]>(size);
    buffer.bytes_ = {buffer.heap_.get(), size};
    return buffer;
}

ShmResult<WritableBuffer> WritableBuffer::Shm(std::size_t size, const ShmConfig& config) {
    auto created = ShmSegment::Create(size, config);
    if (!created.ok()) return {created.status, std::move(created.detail), std::nullopt};
    WritableBuffer buffer;
    buffer.segment_ = std::make_shared<ShmSegment>(std::move(*created.value));
    buffer.bytes_ = buffer.segment_->writable();
    return {ShmStatus::kOk, {}, std::move(buffer)};
}

WritableBuffer::~WritableBuffer() = default;

SharedBuffer WritableBuffer::Seal(std::size_t length) {
    if (length > bytes_.size()) {
        throw std::invalid_argument("WritableBuffer::Seal: length " + std::to_string(length) +
                                    " exceeds size " + std::to_string(bytes_.size()) +
                                    " (or the buffer was already sealed)");
    }
    bytes_ = {};
    if (segment_ != nullptr) return SharedBuffer::InShm(std::move(segment_), length);
    std::shared_ptr<std::byte[]> owner(std::move(heap_));
    const std::byte* data = owner.get();
    return SharedBuffer::Wrap(std::move(owner), data, length);
}

}  // namespace certislam::transport
