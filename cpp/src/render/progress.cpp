// hybridbrdf renderer — progress bar.
#include "hybridbrdf/render/progress.hpp"

#include <cstdio>

namespace hbrdf::render {

ProgressBar::ProgressBar(long total, bool quiet)
    : total_(total > 0 ? total : 1), quiet_(quiet), start_(std::chrono::steady_clock::now()), last_draw_(start_) {
    // Drawn at once: a tile of many samples can take minutes, and a bar tells that the render has begun.
    if (!quiet_) draw(0, false);
}

void ProgressBar::tick() {
    const long done = ++done_;
    if (quiet_) return;
    std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);  // a busy bar is skipped, never waited for
    if (!lock.owns_lock()) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_draw_ < std::chrono::milliseconds(100) && done < total_) return;
    last_draw_ = now;
    draw(done, false);
}

void ProgressBar::finish() {
    if (quiet_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    draw(done_.load(), true);
}

void ProgressBar::stop() {
    if (quiet_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    if (drawn_) std::fputc('\n', stderr);
    drawn_ = false;
}

void ProgressBar::draw(long done, bool final) {
    constexpr int kWidth = 30;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double frac = double(done) / double(total_);
    const int filled = int(frac * kWidth + 0.5);
    char bar[kWidth + 1];
    for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '-';
    bar[kWidth] = '\0';
    if (done > 0) {
        const double eta = elapsed * (1.0 - frac) / frac;
        std::fprintf(stderr, "\rrender [%s] %ld/%ld tiles, %.1f s, ETA %.1f s   ", bar, done, total_, elapsed, eta);
    } else {
        std::fprintf(stderr, "\rrender [%s] %ld/%ld tiles, %.1f s, ETA -   ", bar, done, total_, elapsed);
    }
    if (final) std::fputc('\n', stderr);
    drawn_ = !final;
    std::fflush(stderr);
}

}  // namespace hbrdf::render
