// A watchdog over a team's stop: the process ends within `grace` of the stop request.
#include "bin/stop_within.h"

#include <cstdio>
#include <cstdlib>
#include <future>
#include <thread>

namespace certislam::bin {

void StopWithin(const std::function<void()>& stop, std::chrono::milliseconds grace, int exit_code) {
    std::packaged_task<void()> task(stop);
    std::future<void> stopped = task.get_future();
    std::thread stopper(std::move(task));
    if (stopped.wait_for(grace) == std::future_status::ready) {
        stopper.join();
        stopped.get();
        return;
    }
    std::fprintf(stderr,
                 "certislam: an actor is still inside a long step %lld ms after the stop "
                 "request: exiting without waiting for it\n",
                 static_cast<long long>(grace.count()));
    std::fflush(stdout);
    std::fflush(stderr);
    std::_Exit(exit_code);  // no destructors: the busy thread still uses what they would free
}

}  // namespace certislam::bin
