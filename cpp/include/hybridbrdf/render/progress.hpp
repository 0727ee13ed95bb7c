// hybridbrdf renderer — a progress bar on stderr (tiles done / total, elapsed, ETA).
#pragma once

#include <atomic>
#include <chrono>
#include <mutex>

namespace hbrdf::render {

/// Thread-safe: tick() may be called from every worker. Draws the empty bar
/// when constructed, redraws at most ten times a second, and once more at
/// finish(). Prints nothing when quiet.
class ProgressBar {
public:
    ProgressBar(long total, bool quiet);
    void tick();
    /// Draws the final state and ends the line.
    void finish();
    /// Ends the line of a bar that was drawn, without redrawing it (a failed
    /// or cancelled render), so that the next message starts a line of its own.
    void stop();

private:
    void draw(long done, bool final);
    long total_;
    bool quiet_;
    bool drawn_ = false;  // something is on the line
    std::atomic<long> done_{0};
    std::mutex mutex_;
    std::chrono::steady_clock::time_point start_, last_draw_;
};

}  // namespace hbrdf::render
