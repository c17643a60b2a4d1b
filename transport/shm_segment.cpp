// Same-host shared-memory buffers: create/publish (writer), open/release (reader), reaper.
#include "transport/shm_segment.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <random>
#include <stdexcept>
#include <utility>

#include "transport/shm_internal.h"

namespace certislam::transport {

using shm_detail::HeaderLock;
using shm_detail::kHeaderBytes;
using shm_detail::Mapping;
using shm_detail::SegmentHeader;

namespace {

/// Mappings a reader keeps for segments that are not in use.
constexpr std::size_t kMaxCachedMappings = 16;
/// Longest segment name accepted (NAME_MAX is 255).
constexpr std::size_t kMaxNameLength = 200;

template <class T>
ShmResult<T> Fail(ShmStatus status, std::string detail) {
    return ShmResult<T>{status, std::move(detail), std::nullopt};
}

template <class T>
ShmResult<T> SystemFail(const std::string& what) {
    return Fail<T>(ShmStatus::kSystemError, what + ": " + std::strerror(errno));
}

bool IsNameChar(char c, bool allow_dash) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           (allow_dash && c == '-');
}

/// "/<prefix>-<[A-Za-z0-9_-]+>" and not too long: anything else never reaches shm_open.
bool IsFamilyName(const std::string& name, const std::string& prefix) {
    const std::string head = "/" + prefix + "-";
    if (name.size() <= head.size() || name.size() > kMaxNameLength) return false;
    if (name.compare(0, head.size(), head) != 0) return false;
    for (std::size_t i = head.size(); i < name.size(); ++i) {
        if (!IsNameChar(name[i], true)) return false;
    }
    return true;
}

std::string NewName(const std::string& prefix) {
    static std::atomic<std::uint64_t> counter{0};
    thread_local std::mt19937_64 rng{std::random_device{}()};
    char name[kMaxNameLength];
    std::snprintf(name, sizeof(name), "/%s-%d-%llu-%016llx", prefix.c_str(),
                  static_cast<int>(::getpid()), static_cast<unsigned long long>(counter++),
                  static_cast<unsigned long long>(rng()));
    return name;
}

std::uint64_t LoadMagic(const SegmentHeader* header) {
    return __atomic_load_n(&header->magic, __ATOMIC_ACQUIRE);
}

/// Maps the header page of an open segment read-write; null on failure.
SegmentHeader* MapHeader(int fd) {
    void* p = ::mmap(nullptr, kHeaderBytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    return p == MAP_FAILED ? nullptr : static_cast<SegmentHeader*>(p);
}

void InitHeader(SegmentHeader& header, std::size_t capacity) {
    header.layout = shm_detail::kLayout;
    header.capacity = capacity;
    header.generation = std::random_device{}();  // a name is never reused; this is belt and braces
    pthread_mutexattr_t attr;
    pthread_mutexattr_init(&attr);
    pthread_mutexattr_setpshared(&attr, PTHREAD_PROCESS_SHARED);
    pthread_mutexattr_setrobust(&attr, PTHREAD_MUTEX_ROBUST);
    pthread_mutex_init(&header.mutex, &attr);
    pthread_mutexattr_destroy(&attr);
    shm_detail::AddHolderRef(header);  // not visible to anyone before the magic is stored
    __atomic_store_n(&header.magic, shm_detail::kMagic, __ATOMIC_RELEASE);
}

}  // namespace

void ShmConfig::Validate() const {
    if (prefix.empty() || prefix.size() > 32) {
        throw std::invalid_argument("ShmConfig.prefix: '" + prefix + "' must be 1-32 characters");
    }
    for (char c : prefix) {
        if (!IsNameChar(c, false)) {
            throw std::invalid_argument("ShmConfig.prefix: '" + prefix +
                                        "' must contain only [A-Za-z0-9_]");
        }
    }
    if (loan_ttl.count() <= 0) {
        throw std::invalid_argument("ShmConfig.loan_ttl: " + std::to_string(loan_ttl.count()) +
                                    " ms must be > 0");
    }
    if (max_segment_bytes == 0) throw std::invalid_argument("ShmConfig.max_segment_bytes: 0");
}

v1::ShmDescriptor ToProto(const ShmDescriptor& descriptor) {
    v1::ShmDescriptor message;
    message.set_segment_name(descriptor.segment_name);
    message.set_offset_bytes(descriptor.offset_bytes);
    message.set_byte_length(descriptor.byte_length);
    message.set_generation(descriptor.generation);
    return message;
}

ShmDescriptor FromProto(const v1::ShmDescriptor& message) {
    return ShmDescriptor{message.segment_name(), message.offset_bytes(), message.byte_length(),
                         message.generation()};
}

const char* ToString(ShmStatus status) {
    switch (status) {
        case ShmStatus::kOk:
            return "ok";
        case ShmStatus::kBadName:
            return "bad-name";
        case ShmStatus::kNotFound:
            return "not-found";
        case ShmStatus::kBadSegment:
            return "bad-segment";
        case ShmStatus::kStaleGeneration:
            return "stale-generation";
        case ShmStatus::kOutOfRange:
            return "out-of-range";
        case ShmStatus::kNoLoan:
            return "no-loan";
        case ShmStatus::kLoanExpired:
            return "loan-expired";
        case ShmStatus::kHoldersFull:
            return "holders-full";
        case ShmStatus::kSystemError:
            return "system-error";
    }
    return "unknown";
}

// ---- writer ----

ShmResult<ShmSegment> ShmSegment::Create(std::size_t capacity, const ShmConfig& config) {
    config.Validate();
    if (capacity > config.max_segment_bytes) {
        throw std::invalid_argument("ShmSegment::Create: capacity " + std::to_string(capacity) +
                                    " exceeds ShmConfig.max_segment_bytes");
    }
    auto mapping = std::make_shared<Mapping>();
    mapping->name = NewName(config.prefix);
    mapping->fd = ::shm_open(mapping->name.c_str(), O_CREAT | O_EXCL | O_RDWR | O_CLOEXEC, 0600);
    if (mapping->fd < 0) return SystemFail<ShmSegment>("shm_open " + mapping->name);
    const auto fail = [&](const char* what) {
        auto result = SystemFail<ShmSegment>(std::string(what) + " " + mapping->name);
        ::shm_unlink(mapping->name.c_str());  // never published: nobody else knows the name
        return result;
    };
    if (::ftruncate(mapping->fd, static_cast<off_t>(kHeaderBytes + capacity)) != 0) {
        return fail("ftruncate");
    }
    mapping->header = MapHeader(mapping->fd);
    if (mapping->header == nullptr) return fail("mmap header");
    if (capacity > 0) {
        // Populated at once: the writer's copy then never takes a page fault per 4 KiB.
        void* p = ::mmap(nullptr, capacity, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_POPULATE,
                         mapping->fd, static_cast<off_t>(kHeaderBytes));
        if (p == MAP_FAILED) return fail("mmap payload");
        mapping->payload = static_cast<std::byte*>(p);
        mapping->capacity = capacity;
    }
    InitHeader(*mapping->header, capacity);
    return ShmResult<ShmSegment>{ShmStatus::kOk, {}, ShmSegment(std::move(mapping), config)};
}

ShmSegment::ShmSegment(std::shared_ptr<Mapping> mapping, ShmConfig config)
    : mapping_(std::move(mapping)), config_(std::move(config)) {}

ShmSegment& ShmSegment::operator=(ShmSegment&& other) noexcept {
    if (this != &other) {
        Release();
        mapping_ = std::move(other.mapping_);
        config_ = std::move(other.config_);
    }
    return *this;
}

ShmSegment::~ShmSegment() { Release(); }

void ShmSegment::Release() {
    if (mapping_ == nullptr) return;
    shm_detail::ReleaseAndMaybeUnlink(*mapping_);
    mapping_.reset();
}

std::span<std::byte> ShmSegment::writable() { return {mapping_->payload, mapping_->capacity}; }

std::size_t ShmSegment::capacity() const { return mapping_->capacity; }

const std::string& ShmSegment::name() const { return mapping_->name; }

ShmDescriptor ShmSegment::Publish(std::size_t length, int readers, std::size_t offset) {
    if (offset > capacity() || length > capacity() - offset) {
        throw std::invalid_argument("ShmSegment::Publish: range [" + std::to_string(offset) +
                                    ", +" + std::to_string(length) + ") exceeds capacity " +
                                    std::to_string(capacity()));
    }
    if (readers < 1) throw std::invalid_argument("ShmSegment::Publish: readers must be >= 1");
    SegmentHeader& header = *mapping_->header;
    const HeaderLock lock(&header);
    ++header.generation;
    header.published_offset = offset;
    header.published_length = length;
    header.loans = readers;
    header.loan_deadline_ns =
        shm_detail::MonotonicNowNs() +
        std::chrono::duration_cast<std::chrono::nanoseconds>(config_.loan_ttl).count();
    return ShmDescriptor{mapping_->name, offset, length, header.generation};
}

ShmDescriptor ShmSegment::Lend(std::size_t length, int readers) {
    if (length > capacity()) {
        throw std::invalid_argument("ShmSegment::Lend: length " + std::to_string(length) +
                                    " exceeds capacity " + std::to_string(capacity()));
    }
    if (readers < 1) throw std::invalid_argument("ShmSegment::Lend: readers must be >= 1");
    SegmentHeader& header = *mapping_->header;
    const HeaderLock lock(&header);
    if (header.published_offset != 0 || header.published_length != length) {
        ++header.generation;
        header.published_offset = 0;
        header.published_length = length;
        header.loans = 0;
    }
    if (!shm_detail::LoansPending(header)) header.loans = 0;  // expired ones are void
    header.loans += readers;
    header.loan_deadline_ns =
        shm_detail::MonotonicNowNs() +
        std::chrono::duration_cast<std::chrono::nanoseconds>(config_.loan_ttl).count();
    return ShmDescriptor{mapping_->name, 0, length, header.generation};
}

void ShmSegment::Unlend(int readers) {
    SegmentHeader& header = *mapping_->header;
    const HeaderLock lock(&header);
    header.loans = std::max<std::int64_t>(0, header.loans - readers);
}

bool ShmSegment::Reusable() {
    SegmentHeader& header = *mapping_->header;
    const HeaderLock lock(&header);
    shm_detail::ClearDeadHolders(header);
    return shm_detail::OtherHolders(header) == 0 && shm_detail::OwnRefs(header) <= 1 &&
           !shm_detail::LoansPending(header);
}

// ---- reader ----

ShmView::ShmView(std::shared_ptr<Mapping> mapping, std::span<const std::byte> bytes)
    : mapping_(std::move(mapping)), bytes_(bytes) {}

ShmView& ShmView::operator=(ShmView&& other) noexcept {
    if (this != &other) {
        Release();
        mapping_ = std::move(other.mapping_);
        bytes_ = other.bytes_;
    }
    return *this;
}

ShmView::~ShmView() { Release(); }

void ShmView::Release() {
    if (mapping_ == nullptr) return;
    shm_detail::ReleaseAndMaybeUnlink(*mapping_);
    mapping_.reset();
    bytes_ = {};
}

ShmReader::ShmReader(ShmConfig config) : config_(std::move(config)) { config_.Validate(); }

ShmResult<std::shared_ptr<Mapping>> ShmReader::MappingFor(const std::string& name) {
    using R = ShmResult<std::shared_ptr<Mapping>>;
    if (const auto it = cache_.find(name); it != cache_.end())
        return R{ShmStatus::kOk, {}, it->second};
    auto mapping = std::make_shared<Mapping>();
    mapping->name = name;
    mapping->fd = ::shm_open(name.c_str(), O_RDWR | O_CLOEXEC, 0);
    if (mapping->fd < 0) {
        if (errno == ENOENT) return Fail<std::shared_ptr<Mapping>>(ShmStatus::kNotFound, name);
        return SystemFail<std::shared_ptr<Mapping>>("shm_open " + name);
    }
    struct stat st {};
    if (::fstat(mapping->fd, &st) != 0) return SystemFail<std::shared_ptr<Mapping>>("fstat");
    const auto size = static_cast<std::size_t>(st.st_size);
    if (size < kHeaderBytes) return Fail<std::shared_ptr<Mapping>>(ShmStatus::kBadSegment, name);
    mapping->header = MapHeader(mapping->fd);
    if (mapping->header == nullptr) return SystemFail<std::shared_ptr<Mapping>>("mmap header");
    if (LoadMagic(mapping->header) != shm_detail::kMagic ||
        mapping->header->layout != shm_detail::kLayout ||
        mapping->header->capacity != size - kHeaderBytes) {
        return Fail<std::shared_ptr<Mapping>>(ShmStatus::kBadSegment,
                                              name + ": not an initialised segment");
    }
    if (size > kHeaderBytes) {
        // Read-only payload; populated at once (one pass in the kernel instead of a fault/page).
        void* p = ::mmap(nullptr, size - kHeaderBytes, PROT_READ, MAP_SHARED | MAP_POPULATE,
                         mapping->fd, static_cast<off_t>(kHeaderBytes));
        if (p == MAP_FAILED) return SystemFail<std::shared_ptr<Mapping>>("mmap payload");
        mapping->payload = static_cast<std::byte*>(p);
        mapping->capacity = size - kHeaderBytes;
    }
    cache_[name] = mapping;
    return R{ShmStatus::kOk, {}, std::move(mapping)};
}

ShmResult<ShmView> ShmReader::Open(const ShmDescriptor& d) {
    if (!IsFamilyName(d.segment_name, config_.prefix)) {
        return Fail<ShmView>(ShmStatus::kBadName, "'" + d.segment_name + "' is not a /" +
                                                      config_.prefix + "-* segment name");
    }
    auto mapped = MappingFor(d.segment_name);
    if (!mapped.ok()) return Fail<ShmView>(mapped.status, std::move(mapped.detail));
    std::shared_ptr<Mapping> mapping = std::move(*mapped.value);
    SegmentHeader& header = *mapping->header;
    {
        const HeaderLock lock(&header);
        if (header.unlinked != 0) {
            cache_.erase(d.segment_name);
            return Fail<ShmView>(ShmStatus::kNotFound, d.segment_name + " was reclaimed");
        }
        if (d.generation != header.generation) {
            return Fail<ShmView>(ShmStatus::kStaleGeneration,
                                 "generation " + std::to_string(d.generation) +
                                     " != " + std::to_string(header.generation));
        }
        const std::uint64_t begin = header.published_offset;
        const std::uint64_t end = begin + header.published_length;
        if (d.offset_bytes < begin || d.offset_bytes > end ||
            d.byte_length > end - d.offset_bytes) {
            std::string detail = "offset ";
            detail += std::to_string(d.offset_bytes) + " length " + std::to_string(d.byte_length);
            return Fail<ShmView>(ShmStatus::kOutOfRange, detail + " outside the published bytes");
        }
        if (header.loans <= 0) return Fail<ShmView>(ShmStatus::kNoLoan, "no reference left");
        if (shm_detail::MonotonicNowNs() > header.loan_deadline_ns) {
            return Fail<ShmView>(ShmStatus::kLoanExpired, "published longer than loan_ttl ago");
        }
        if (!shm_detail::AddHolderRef(header)) {
            return Fail<ShmView>(ShmStatus::kHoldersFull, d.segment_name);
        }
        --header.loans;
    }
    const std::span<const std::byte> bytes(mapping->payload + d.offset_bytes, d.byte_length);
    Trim();
    return ShmResult<ShmView>{ShmStatus::kOk, {}, ShmView(std::move(mapping), bytes)};
}

void ShmReader::Trim() {
    for (auto it = cache_.begin(); it != cache_.end();) {
        const bool gone = __atomic_load_n(&it->second->header->unlinked, __ATOMIC_RELAXED) != 0;
        const bool over = cache_.size() > kMaxCachedMappings;
        if (it->second.use_count() == 1 && (gone || over)) {
            it = cache_.erase(it);
        } else {
            ++it;
        }
    }
}

// ---- reaper ----

std::size_t ReapShmSegments(const ShmConfig& config) {
    config.Validate();
    DIR* dir = ::opendir("/dev/shm");
    if (dir == nullptr) return 0;
    std::size_t reaped = 0;
    const auto ttl_s = std::chrono::duration_cast<std::chrono::seconds>(config.loan_ttl).count();
    while (const dirent* entry = ::readdir(dir)) {
        const std::string name = std::string("/") + entry->d_name;
        if (!IsFamilyName(name, config.prefix)) continue;
        Mapping mapping;
        mapping.name = name;
        mapping.fd = ::shm_open(name.c_str(), O_RDWR | O_CLOEXEC, 0);
        struct stat st {};
        if (mapping.fd < 0 || ::fstat(mapping.fd, &st) != 0) continue;
        if (static_cast<std::size_t>(st.st_size) >= kHeaderBytes)
            mapping.header = MapHeader(mapping.fd);
        if (mapping.header == nullptr || LoadMagic(mapping.header) != shm_detail::kMagic) {
            // Never initialised (its creator died half-way): reclaim once it is clearly old.
            if (::time(nullptr) - st.st_mtime > ttl_s && ::shm_unlink(name.c_str()) == 0) ++reaped;
            continue;
        }
        const HeaderLock lock(mapping.header);
        if (shm_detail::UnlinkIfUnheld(mapping)) ++reaped;
    }
    ::closedir(dir);
    return reaped;
}

bool ShmSegmentExists(const std::string& name) {
    const int fd = ::shm_open(name.c_str(), O_RDONLY | O_CLOEXEC, 0);
    if (fd < 0) return false;
    ::close(fd);
    return true;
}

}  // namespace certislam::transport
