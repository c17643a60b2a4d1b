// Append-only log of wire frames behind a header with the mission's identity; a torn last record
// (crash mid-write) is detected and cut off, a log of another mission is never replayed.
#include "actors/durable_log.h"

#include <filesystem>
#include <sstream>
#include <stdexcept>

namespace certislam::actors {
namespace {

constexpr std::uint32_t kMaxFrames = 64;
constexpr std::uint64_t kMaxFrameBytes = std::uint64_t{1} << 32;
constexpr std::uint32_t kMaxIdentityBytes = 1u << 20;
constexpr char kMagic[] = "CERTISLAM-LOG 1\n";  // 16 bytes, then u32 length and the identity
constexpr std::size_t kMagicBytes = sizeof(kMagic) - 1;

template <class T>
bool ReadValue(std::ifstream& in, T* value) {
    return static_cast<bool>(in.read(reinterpret_cast<char*>(value), sizeof(T)));
}

/// Reads the header; false when the file does not start with one.
bool ReadHeader(std::ifstream& in, std::string* identity) {
    std::string magic(kMagicBytes, '\0');
    std::uint32_t size = 0;
    if (!in.read(magic.data(), kMagicBytes) || magic != kMagic || !ReadValue(in, &size) ||
        size > kMaxIdentityBytes) {
        return false;
    }
    identity->assign(size, '\0');
    return static_cast<bool>(in.read(identity->data(), size));
}

/// The first line where two identities differ, as "LOG_LINE (log) / OURS (this mission)".
std::string FirstDifference(const std::string& logged, const std::string& ours) {
    std::istringstream a(logged), b(ours);
    std::string la, lb;
    while (true) {
        const bool more_a = static_cast<bool>(std::getline(a, la));
        const bool more_b = static_cast<bool>(std::getline(b, lb));
        if (!more_a && !more_b) return "";
        if (!more_a) la = "(nothing)";
        if (!more_b) lb = "(nothing)";
        if (la != lb || !more_a || !more_b) {
            std::string text = "'";
            text += la;
            text += "' in the log, '";
            text += lb;
            text += "' now";
            return text;
        }
    }
}

std::string MoveAside(const std::string& path) {
    for (int n = 1;; ++n) {
        std::string target = path + ".stale-" + std::to_string(n);
        if (!std::filesystem::exists(target)) {
            std::filesystem::rename(path, target);
            return target;
        }
    }
}

}  // namespace

DurableLog::DurableLog(const std::string& path, const std::string& identity)
    : path_(path), out_(path, std::ios::binary | std::ios::app) {
    if (!out_) throw std::runtime_error(path + ": cannot open the durable log for appending");
    if (identity.size() > kMaxIdentityBytes) {
        throw std::runtime_error(path + ": mission identity over 1 MiB");
    }
    if (out_.tellp() == 0) {
        const auto size = static_cast<std::uint32_t>(identity.size());
        out_.write(kMagic, kMagicBytes);
        out_.write(reinterpret_cast<const char*>(&size), sizeof(size));
        out_.write(identity.data(), static_cast<std::streamsize>(size));
        out_.flush();
        if (!out_) throw std::runtime_error(path_ + ": write to the durable log failed");
    }
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
    if (!in || in.peek() == std::ifstream::traits_type::eof()) return result;
    if (!ReadHeader(in, &result.identity)) {
        result.has_header = false;
        return result;
    }
    result.good_bytes = static_cast<std::uint64_t>(in.tellg());
    const std::uint64_t file_bytes = std::filesystem::file_size(path);
    for (std::uint32_t count = 0; ReadValue(in, &count);) {
        if (count == 0 || count > kMaxFrames) {
            result.torn_tail = true;  // not a record header: nothing after it can be trusted
            break;
        }
        std::vector<zmq::message_t> frames;
        bool complete = true;
        for (std::uint32_t k = 0; k < count && complete; ++k) {
            std::uint64_t size = 0;
            // A size beyond the bytes left is a torn or forged record: refused before allocating.
            complete = ReadValue(in, &size) && size <= kMaxFrameBytes &&
                       size <= file_bytes - static_cast<std::uint64_t>(in.tellg());
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
        } else if (result.bad_records++ == 0) {
            result.first_bad_offset = result.good_bytes;
        }
        result.good_bytes = static_cast<std::uint64_t>(in.tellg());
    }
    // A few bytes of a record header alone are a torn tail too.
    if (file_bytes > result.good_bytes) result.torn_tail = true;
    return result;
}

DurableLogCheck PrepareDurableLog(const std::string& path, const std::string& identity,
                                  StaleLogPolicy policy) {
    DurableLogCheck check;
    std::error_code error;
    if (std::filesystem::file_size(path, error) == 0 || error) return check;  // nothing logged
    const DurableLogRead read = ReadDurableLog(path);
    std::string problem;
    if (!read.has_header) {
        problem = "not a certislam durable log (no header)";
    } else if (read.identity != identity) {
        problem = "written by another mission: " + FirstDifference(read.identity, identity);
    } else if (read.bad_records > 0) {
        problem = std::to_string(read.bad_records) + " corrupt record(s), the first at byte " +
                  std::to_string(read.first_bad_offset);
    }
    if (!problem.empty()) {
        if (policy == StaleLogPolicy::kRefuse) {
            throw std::runtime_error(path + ": " + problem +
                                     "; refusing to replay it (move it away, or set "
                                     "log_stale: move_aside)");
        }
        check.moved_to = MoveAside(path);
        return check;
    }
    check.records = static_cast<int>(read.messages.size());
    if (read.torn_tail) {
        std::filesystem::resize_file(path, read.good_bytes);
        check.truncated_tail = true;
    }
    return check;
}

}  // namespace certislam::actors
