// Ending a command within a bound of its deadline, whatever the team's threads are doing.
#pragma once

#include <chrono>
#include <functional>

namespace certislam::bin {

/// How long a command waits for its actors after the deadline (the rest of the second after
/// `--timeout` goes to writing the report).
inline constexpr std::chrono::milliseconds kStopGrace{250};

/// Runs `stop` (which asks a team's actors to stop and joins them). Actors end at their next
/// handler boundary; if one is inside a long step (a registration, a TSDF integration) and `stop`
/// has not returned after `grace`, flushes stdout and stderr and ends the process with
/// `exit_code`. Call it after the report is printed: outputs are written and durable logs are
/// flushed per record, so nothing is lost.
void StopWithin(const std::function<void()>& stop, std::chrono::milliseconds grace, int exit_code);

}  // namespace certislam::bin
