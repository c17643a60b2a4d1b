// Append-only log of wire frames; a torn last record (crash mid-write) is detected and ignored.
#include "actors/durable_log.h"

#include <stdexcept>

namespace certislam::actors {
namespace {

constexpr std::uint32_t kMaxFrames = 64;

template <class T>
bool ReadValue(std::ifstream& in, T* value) {
    return static_cast<bool>(in.read(reinterpret_cast<char*>(value), sizeof(T)));
}

}  // namespace

DurableLog::DurableLog(const std::string& path)
    : path_(path), out_(path, std::ios::binary | std::ios::app) {
    if (!out_) throw std::runtime_error(path + ": cannot open the durable log for appending");
}

void DurableLog::Append(const transport::Message& message) {
    const auto frames = transport::Encode(message);
    const auto count = static_cast<std::uint32_t>(frames.size());
    out_.write(reinterpret_cast<const char*>(&count), sizeof(count));
    for (const auto& frame : frames) {
        const auto size = static_cast<std::uint64_t>(frame.size());
        out_.write(reinterpret_cast<const char*>(&size), sizeof(size));
        out_.write(static_cast<const char*>(frame.data()), static_cast<std::streamsize>(size));
    }
    out_.flush();
    if (!out_) throw std::runtime_error(path_ + ": write to the durable log failed");
    ++appended_;
}

DurableLogRead ReadDurableLog(const std::string& path) {
    DurableLogRead result;
    std::ifstream in(path, std::ios::binary);
    if (!in) return result;
    for (std::uint32_t count = 0; ReadValue(in, &count);) {
        if (count == 0 || count > kMaxFrames) {
            result.torn_tail = true;  // not a record header: nothing after it can be trusted
            break;
        }
        std::vector<zmq::message_t> frames;
        bool complete = true;
        for (std::uint32_t k = 0; k < count && complete; ++k) {
            std::uint64_t size = 0;
            complete = ReadValue(in, &size) && size <= (std::uint64_t{1} << 32);
            if (!complete) break;
            zmq::message_t frame(static_cast<std::size_t>(size));
            complete = static_cast<bool>(
                in.read(static_cast<char*>(frame.data()), static_cast<std::streamsize>(size)));
            frames.push_back(std::move(frame));
        }
        if (!complete) {
            result.torn_tail = true;
            break;
        }
        auto decoded = transport::Decode(std::move(frames));
        if (decoded.status == transport::DecodeResult::Status::kOk) {
            result.messages.push_back(std::move(*decoded.message));
        } else {
            ++result.bad_records;
        }
    }
    return result;
}

}  // namespace certislam::actors
