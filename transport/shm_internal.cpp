// Internals of the shared-memory segments: header locking, holder liveness, reclamation.
#include "transport/shm_internal.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <stdexcept>
#include <string>

namespace certislam::transport::shm_detail {

Mapping::~Mapping() {
    if (payload != nullptr && capacity > 0) ::munmap(payload, capacity);
    if (header != nullptr) ::munmap(header, kHeaderBytes);
    if (fd >= 0) ::close(fd);
}

HeaderLock::HeaderLock(SegmentHeader* header) : header_(header) {
    const int rc = pthread_mutex_lock(&header_->mutex);
    if (rc == EOWNERDEAD) {
        // The previous owner died inside the lock. Each update under it is a few stores that
        // leave the header consistent at any point, and dead holders are cleared by liveness.
        pthread_mutex_consistent(&header_->mutex);
    } else if (rc != 0) {
        throw std::runtime_error(std::string("shm: header mutex lock failed: ") +
                                 std::strerror(rc));
    }
}

HeaderLock::~HeaderLock() { pthread_mutex_unlock(&header_->mutex); }

std::uint64_t ProcessStartTicks(pid_t pid) {
    char path[64];
    std::snprintf(path, sizeof(path), "/proc/%d/stat", static_cast<int>(pid));
    std::FILE* file = std::fopen(path, "re");
    if (file == nullptr) return 0;
    char buffer[1024];
    const std::size_t n = std::fread(buffer, 1, sizeof(buffer) - 1, file);
    std::fclose(file);
    buffer[n] = '\0';
    // "pid (comm) state ppid ..." where comm may hold spaces and ')': parse after the last ')'.
    const char* close = std::strrchr(buffer, ')');
    if (close == nullptr || close[1] == '\0') return 0;
    const char* p = close + 2;
    const char state = *p;
    if (state == 'Z' || state == 'X' || state == 'x') return 0;  // dead, not yet reaped
    // Field 3 is the state; the start time is field 22.
    for (int field = 3; field < 22 && *p != '\0'; ++p) {
        if (*p == ' ') ++field;
    }
    return std::strtoull(p, nullptr, 10);
}

namespace {

struct Self {
    pid_t pid;
    std::uint64_t start_ticks;
};

/// This process's identity (re-read after a fork: the child is another holder).
const Self& Me() {
    thread_local Self self{0, 0};
    const pid_t pid = ::getpid();
    if (self.pid != pid) self = Self{pid, ProcessStartTicks(pid)};
    return self;
}

bool IsMe(const HolderSlot& slot) {
    const Self& me = Me();
    return slot.pid == me.pid && slot.start_ticks == me.start_ticks;
}

}  // namespace

void ClearDeadHolders(SegmentHeader& header) {
    for (HolderSlot& slot : header.holders) {
        if (slot.pid == 0 || IsMe(slot)) continue;
        if (ProcessStartTicks(slot.pid) != slot.start_ticks) slot = HolderSlot{};
    }
}

bool AddHolderRef(SegmentHeader& header) {
    HolderSlot* free_slot = nullptr;
    for (HolderSlot& slot : header.holders) {
        if (slot.pid != 0 && IsMe(slot)) {
            ++slot.refs;
            return true;
        }
        if (slot.pid == 0 && free_slot == nullptr) free_slot = &slot;
    }
    if (free_slot == nullptr) {
        ClearDeadHolders(header);
        for (HolderSlot& slot : header.holders) {
            if (slot.pid == 0) {
                free_slot = &slot;
                break;
            }
        }
    }
    if (free_slot == nullptr) return false;
    *free_slot = HolderSlot{Me().pid, 1, Me().start_ticks};
    return true;
}

void DropHolderRef(SegmentHeader& header) {
    for (HolderSlot& slot : header.holders) {
        if (slot.pid != 0 && IsMe(slot)) {
            if (--slot.refs == 0) slot = HolderSlot{};
            return;
        }
    }
}

std::uint32_t OwnRefs(const SegmentHeader& header) {
    for (const HolderSlot& slot : header.holders) {
        if (slot.pid != 0 && IsMe(slot)) return slot.refs;
    }
    return 0;
}

int OtherHolders(const SegmentHeader& header) {
    int n = 0;
    for (const HolderSlot& slot : header.holders) {
        if (slot.pid != 0 && !IsMe(slot)) ++n;
    }
    return n;
}

bool LoansPending(const SegmentHeader& header) {
    return header.loans > 0 && MonotonicNowNs() <= header.loan_deadline_ns;
}

bool UnlinkIfUnheld(Mapping& mapping) {
    SegmentHeader& header = *mapping.header;
    if (header.unlinked != 0) return false;
    ClearDeadHolders(header);
    if (OwnRefs(header) > 0 || OtherHolders(header) > 0 || LoansPending(header)) return false;
    header.unlinked = 1;
    ::shm_unlink(mapping.name.c_str());
    return true;
}

void ReleaseAndMaybeUnlink(Mapping& mapping) {
    const HeaderLock lock(mapping.header);
    DropHolderRef(*mapping.header);
    UnlinkIfUnheld(mapping);
}

std::int64_t MonotonicNowNs() {
    timespec ts{};
    ::clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

}  // namespace certislam::transport::shm_detail
