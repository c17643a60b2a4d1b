// A robot's durable log: messages it must not lose (its keyframes with their clouds, the loop
// closures it accepted) appended to a file as their wire frames, read back on restart.
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
    bool torn_tail = false;  ///< the last record was cut short (a crash mid-append): ignored
    int bad_records = 0;     ///< complete records whose frames did not decode: skipped
};

/// Reads every record of the log at `path` (a missing file reads as empty).
DurableLogRead ReadDurableLog(const std::string& path);

/// Appends messages to a log file, each flushed before Append returns.
class DurableLog {
  public:
    /// Opens `path` for appending (creates it). Throws std::runtime_error naming the file.
    explicit DurableLog(const std::string& path);
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
