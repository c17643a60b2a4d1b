// The shared-memory path of an ipc:// edge: lending on send, mapping on receive.
#include "transport/shm_edge.h"

#include <bit>
#include <chrono>
#include <cstring>
#include <string>

#include "transport/shm_internal.h"

namespace certislam::transport {

namespace {

/// Largest serialized descriptor accepted (a name of at most 200 characters and three varints).
constexpr std::size_t kMaxDescriptorBytes = 512;
/// Smallest pooled segment.
constexpr std::size_t kMinPoolSegmentBytes = 64 * 1024;

bool IsLargeInline(const Message& message, std::size_t i, std::size_t threshold) {
    return message.envelope.frames(static_cast<int>(i)).kind() == v1::FRAME_KIND_INLINE &&
           message.frames[i].size() >= threshold;
}

std::int64_t NowNs() { return shm_detail::MonotonicNowNs(); }

}  // namespace

void ShmLoans::Add(std::shared_ptr<ShmSegment> segment, int readers) {
    loans_.emplace_back(std::move(segment), readers);
}

void ShmLoans::Revoke() {
    for (auto& [segment, readers] : loans_) segment->Unlend(readers);
    loans_.clear();
}

ShmLender::ShmLender(ShmConfig config, std::size_t threshold_bytes, std::size_t pool_segments)
    : config_(std::move(config)), threshold_(threshold_bytes), pool_limit_(pool_segments) {
    config_.Validate();
    MaybeReap();
}

void ShmLender::MaybeReap() {
    const std::int64_t now = NowNs();
    if (now < next_reap_ns_) return;
    ReapShmSegments(config_);
    next_reap_ns_ =
        now + std::chrono::duration_cast<std::chrono::nanoseconds>(config_.loan_ttl).count();
}

bool ShmLender::Wants(const Message& message) const {
    for (std::size_t i = 0; i < message.frames.size(); ++i) {
        if (IsLargeInline(message, i, threshold_)) return true;
    }
    return false;
}

std::shared_ptr<ShmSegment> ShmLender::Take(std::size_t bytes) {
    const std::size_t capacity = std::bit_ceil(std::max(bytes, kMinPoolSegmentBytes));
    for (const auto& segment : pool_) {
        if (segment->capacity() == capacity && segment->Reusable()) return segment;
    }
    if (pool_.size() >= pool_limit_) {
        // Make room by dropping an idle segment of another size; none idle: a one-off segment.
        for (auto it = pool_.begin(); it != pool_.end(); ++it) {
            if ((*it)->Reusable()) {
                pool_.erase(it);
                break;
            }
        }
    }
    auto created = ShmSegment::Create(pool_.size() < pool_limit_ ? capacity : bytes, config_);
    if (!created.ok()) return nullptr;
    auto segment = std::make_shared<ShmSegment>(std::move(*created.value));
    if (pool_.size() < pool_limit_) pool_.push_back(segment);
    return segment;
}

void ShmLender::Lend(Message& wire, int readers, ShmLoans& loans, ShmLendStats& stats) {
    MaybeReap();
    for (std::size_t i = 0; i < wire.frames.size(); ++i) {
        if (!IsLargeInline(wire, i, threshold_)) continue;
        const SharedBuffer& frame = wire.frames[i];
        std::shared_ptr<ShmSegment> segment = frame.shm_segment();
        ShmDescriptor descriptor;
        if (segment != nullptr) {
            descriptor = segment->Lend(frame.size(), readers);
            ++stats.lent;
        } else {
            segment = Take(frame.size());
            if (segment == nullptr) {
                ++stats.fallback;
                continue;
            }
            const std::int64_t start = NowNs();
            std::memcpy(segment->writable().data(), frame.data(), frame.size());
            stats.copy_ns += static_cast<std::uint64_t>(NowNs() - start);
            ++stats.copied;
            descriptor = segment->Publish(frame.size(), readers);
        }
        loans.Add(segment, readers);
        const std::string bytes = ToProto(descriptor).SerializeAsString();
        auto* info = wire.envelope.mutable_frames(static_cast<int>(i));
        info->set_kind(v1::FRAME_KIND_SHM_DESCRIPTOR);
        info->set_byte_length(bytes.size());
        info->set_payload_byte_length(frame.size());
        wire.frames[i] = SharedBuffer::Copy(bytes.data(), bytes.size());
    }
}

ShmResolver::ShmResolver(ShmConfig config) : reader_(std::move(config)) {}

bool HasShmFrames(const Message& message) {
    for (const auto& info : message.envelope.frames()) {
        if (info.kind() == v1::FRAME_KIND_SHM_DESCRIPTOR) return true;
    }
    return false;
}

bool ShmResolver::Resolve(Message& message, std::string& detail) {
    for (std::size_t i = 0; i < message.frames.size(); ++i) {
        auto* info = message.envelope.mutable_frames(static_cast<int>(i));
        if (info->kind() != v1::FRAME_KIND_SHM_DESCRIPTOR) continue;
        const SharedBuffer& frame = message.frames[i];
        v1::ShmDescriptor proto;
        if (frame.size() > kMaxDescriptorBytes ||
            !proto.ParseFromArray(frame.data(), static_cast<int>(frame.size()))) {
            detail = "frame " + std::to_string(i) + ": descriptor bytes do not parse";
            return false;
        }
        const ShmDescriptor descriptor = FromProto(proto);
        if (descriptor.byte_length != info->payload_byte_length()) {
            detail = "frame " + std::to_string(i) + ": descriptor length " +
                     std::to_string(descriptor.byte_length) + " != declared " +
                     std::to_string(info->payload_byte_length());
            return false;
        }
        auto opened = reader_.Open(descriptor);
        if (!opened.ok()) {
            detail = std::string(ToString(opened.status)) + ": " + opened.detail;
            return false;
        }
        auto view = std::make_shared<ShmView>(std::move(*opened.value));
        const auto bytes = view->bytes();
        message.frames[i] = SharedBuffer::Wrap(std::move(view), bytes.data(), bytes.size());
        info->set_kind(v1::FRAME_KIND_INLINE);
        info->set_byte_length(bytes.size());
        info->set_payload_byte_length(bytes.size());
    }
    return true;
}

}  // namespace certislam::transport
