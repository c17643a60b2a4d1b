// A robot's durable log: messages it must not lose (its keyframes with their clouds, the loop
// closures it accepted) appended to a file as their wire frames, read back on restart. The file
// starts with the mission's identity, so a log is never replayed into another mission.
#pragma once

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "transport/message.h"

namespace certislam::actors {

/// What reading a log gave.
struct DurableLogRead {
    std::vector<transport::Message> messages;  ///< in append order
    std::string identity;                      ///< the mission identity in the header
    bool has_header = true;  ///< false: a non-empty file without a valid header (nothing read)
    bool torn_tail = false;  ///< the last record was cut short (a crash mid-append): ignored
    int bad_records = 0;     ///< complete records whose frames did not decode: skipped
    std::uint64_t first_bad_offset = 0;  ///< byte offset of the first bad record
    std::uint64_t good_bytes = 0;        ///< header and complete records: a torn tail starts here
};

/// Reads every record of the log at `path` (a missing or empty file reads as empty).
DurableLogRead ReadDurableLog(const std::string& path);

/// What to do at start with a log of another mission, without a header, or with a corrupt record.
enum class StaleLogPolicy {
    kRefuse,     ///< throw: the user decides
    kMoveAside,  ///< rename it to PATH.stale-N and start a new log
};

/// What PrepareDurableLog found.
struct DurableLogCheck {
    int records = 0;              ///< complete records that will be replayed
    bool truncated_tail = false;  ///< a torn last record (crash mid-append) was cut off
    std::string moved_to;         ///< where a stale log went (kMoveAside), else empty
};

/// Checks, before the robot starts, that the log at `path` was written for `identity` (the
/// mission's configuration, robot id and key, as text). A missing log is fine; a torn last record
/// is cut off so that appends continue a readable log; a log of another mission, without a header
/// or with a corrupt record is refused (std::runtime_error naming the file and the first differing
/// line or the byte offset) or moved aside, by `policy`.
DurableLogCheck PrepareDurableLog(const std::string& path, const std::string& identity,
                                  StaleLogPolicy policy);

/// Appends messages to a log file, each flushed before Append returns.
class DurableLog {
  public:
    /// Opens `path` for appending (creates it, with `identity` in a new file's header). Throws
    /// std::runtime_error naming the file.
    explicit DurableLog(const std::string& path, const std::string& identity = "");
    /// Appends one message as its frames: u32 frame count, then per frame u64 size + bytes.
    void Append(const transport::Message& message);
    /// Records appended by this object.
    int appended() const { return appended_; }

  private:
    std::string path_;
    std::ofstream out_;
    int appended_ = 0;
};

}  // namespace certislam::actors
