// rayscope's ray log for a student's C++ ray tracer: #include "raylog.hpp", then add one line
// where each kind of ray is cast (see docs/check.md in rayscope). Header-only, C++17. It logs
// nothing, and costs one test of a bool per call, unless the environment variable RAYSCOPE_LOG
// names the log file. Safe with threads (std::thread, OpenMP).
//
// Vectors may be anything with members x, y, z (colours: r, g, b, or x, y, z) or indexable
// [0], [1], [2]; for another type, overload raylog_xyz(const YourType&) returning
// std::array<double, 3> in your type's namespace.
#ifndef RAYSCOPE_RAYLOG_HPP
#define RAYSCOPE_RAYLOG_HPP

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <set>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace raylog {
namespace detail {

using V3 = std::array<double, 3>;

template <class T, class = void>
struct has_xyz : std::false_type {};
template <class T>
struct has_xyz<T, std::void_t<decltype(std::declval<const T&>().x), decltype(std::declval<const T&>().z)>>
    : std::true_type {};
template <class T, class = void>
struct has_rgb : std::false_type {};
template <class T>
struct has_rgb<T, std::void_t<decltype(std::declval<const T&>().r), decltype(std::declval<const T&>().b)>>
    : std::true_type {};
template <class T, class = void>
struct has_adapter : std::false_type {};
template <class T>
struct has_adapter<T, std::void_t<decltype(raylog_xyz(std::declval<const T&>()))>> : std::true_type {};

template <class T>
V3 xyz(const T& v) {
    if constexpr (has_adapter<T>::value)
        return raylog_xyz(v);
    else if constexpr (has_xyz<T>::value)
        return {double(v.x), double(v.y), double(v.z)};
    else if constexpr (has_rgb<T>::value)
        return {double(v.r), double(v.g), double(v.b)};
    else
        return {double(v[0]), double(v[1]), double(v[2])};
}

// One logged ray of the current pixel sample.
struct Rec {
    const char* kind = nullptr;  // nullptr: not said (rayscope infers it)
    int parent = -1;             // index in the sample's list; -1: none
    V3 origin{}, direction{};
    bool awaiting = false;  // cast, its hit not logged yet
    bool traced = false;    // hit() or miss() was called for it
    bool missed = false;
    V3 point{}, normal{};
    bool shadow = false, blocked = false;
    V3 light{};
    bool has_color = false;
    V3 color{};
};

struct Sample;

// The log file, the filters and every thread's current sample.
struct Log {
    std::FILE* out = nullptr;
    std::mutex gate;
    std::vector<Sample*> samples;
    std::set<std::pair<int, int>> pixels;
    bool use_pixels = false, use_rect = false;
    int rect[4] = {0, 0, 0, 0};
    int step = 0;
    std::set<int> sample_filter;
    bool use_samples = false;

    Log();
    ~Log() { close(); }
    void close();
    void write(Sample& s);  // under gate
    bool wanted(int x, int y, int s) const {
        if (use_pixels && !pixels.count({x, y})) return false;
        if (use_rect && (x < rect[0] || y < rect[1] || x > rect[2] || y > rect[3])) return false;
        if (step > 0 && (x % step != 0 || y % step != 0)) return false;
        return !use_samples || sample_filter.count(s);
    }
};

inline Log& log() {
    static Log l;
    return l;
}

// One thread's current pixel sample, written whole when the thread starts its next one, when
// the thread ends, or at exit.
struct Sample {
    bool active = false;
    int x = 0, y = 0, index = 0;
    std::vector<Rec> recs;
    Sample() {
        Log& l = log();
        std::lock_guard<std::mutex> g(l.gate);
        l.samples.push_back(this);
    }
    ~Sample() {
        Log& l = log();
        std::lock_guard<std::mutex> g(l.gate);
        l.write(*this);
        for (auto it = l.samples.begin(); it != l.samples.end(); ++it)
            if (*it == this) {
                l.samples.erase(it);
                break;
            }
    }
};

inline Sample& current() {
    thread_local Sample s;
    return s;
}

inline bool ints(const char* text, std::vector<int>& out) {
    std::string t(text);
    size_t i = 0;
    while (i < t.size()) {
        while (i < t.size() && (t[i] == ',' || t[i] == ' ')) ++i;
        if (i == t.size()) break;
        char* end = nullptr;
        long v = std::strtol(t.c_str() + i, &end, 10);
        if (end == t.c_str() + i) return false;
        out.push_back(int(v));
        i = size_t(end - t.c_str());
        if (i < t.size() && t[i] != ',' && t[i] != ' ') return false;
    }
    return true;
}

inline bool env_on() {
    const char* p = std::getenv("RAYSCOPE_LOG");
    return p && *p;
}

inline Log::Log() {
    const char* path = std::getenv("RAYSCOPE_LOG");
    const char* bad = nullptr;
    std::vector<int> v;
    if (const char* e = std::getenv("RAYSCOPE_LOG_PIXELS"); e && *e) {
        use_pixels = true;
        std::string t(e);
        size_t i = 0;
        while (i < t.size()) {
            size_t j = t.find_first_of(" ;", i);
            if (j == std::string::npos) j = t.size();
            std::vector<int> xy;
            if (j > i && (!ints(t.substr(i, j - i).c_str(), xy) || xy.size() != 2)) bad = "RAYSCOPE_LOG_PIXELS";
            if (xy.size() == 2) pixels.insert({xy[0], xy[1]});
            i = j + 1;
        }
    }
    if (const char* e = std::getenv("RAYSCOPE_LOG_RECT"); e && *e) {
        use_rect = true;
        v.clear();
        if (!ints(e, v) || v.size() != 4)
            bad = "RAYSCOPE_LOG_RECT";
        else
            for (int i = 0; i < 4; ++i) rect[i] = v[i];
    }
    if (const char* e = std::getenv("RAYSCOPE_LOG_STEP"); e && *e) {
        v.clear();
        if (!ints(e, v) || v.size() != 1 || v[0] < 1)
            bad = "RAYSCOPE_LOG_STEP";
        else
            step = v[0];
    }
    if (const char* e = std::getenv("RAYSCOPE_LOG_SAMPLES"); e && *e) {
        use_samples = true;
        v.clear();
        if (!ints(e, v)) bad = "RAYSCOPE_LOG_SAMPLES";
        sample_filter.insert(v.begin(), v.end());
    }
    if (bad) {
        std::fprintf(stderr, "raylog: not logging: %s is malformed\n", bad);
        return;
    }
    if (path && *path && !(out = std::fopen(path, "w")))
        std::fprintf(stderr, "raylog: not logging: cannot write %s\n", path);
}

inline void num(std::string& b, double v) {
    char t[32];
    if (std::isfinite(v))
        std::snprintf(t, sizeof t, "%.17g", v);
    else
        std::snprintf(t, sizeof t, "null");
    b += t;
}

inline void vec(std::string& b, const V3& v) {
    b += '[';
    num(b, v[0]);
    b += ',';
    num(b, v[1]);
    b += ',';
    num(b, v[2]);
    b += ']';
}

inline void Log::write(Sample& s) {
    if (!out || s.recs.empty()) {
        s.recs.clear();
        return;
    }
    std::string b;
    for (size_t i = 0; i < s.recs.size(); ++i) {
        const Rec& r = s.recs[i];
        b += "{\"pixel\":[" + std::to_string(s.x) + "," + std::to_string(s.y) + "],\"sample\":" +
             std::to_string(s.index) + ",\"id\":" + std::to_string(i) + ",\"parent\":";
        b += r.parent < 0 ? std::string("null") : std::to_string(r.parent);
        if (r.kind) b += std::string(",\"kind\":\"") + r.kind + "\"";
        b += ",\"origin\":";
        vec(b, r.origin);
        b += ",\"direction\":";
        vec(b, r.direction);
        if (r.shadow) {
            b += ",\"light\":";
            vec(b, r.light);
            b += r.blocked ? ",\"blocked_by\":true" : ",\"blocked_by\":null";
        } else if (r.traced) {
            b += ",\"hit\":";
            if (r.missed) {
                b += "null";
            } else {
                b += "{\"point\":";
                vec(b, r.point);
                b += ",\"normal\":";
                vec(b, r.normal);
                b += "}";
            }
        }
        if (r.has_color) {
            b += ",\"color\":";
            vec(b, r.color);
        }
        b += "}\n";
    }
    std::fwrite(b.data(), 1, b.size(), out);
    s.recs.clear();
}

inline void Log::close() {
    std::lock_guard<std::mutex> g(gate);
    if (!out) return;
    for (Sample* s : samples) write(*s);
    std::fclose(out);
    out = nullptr;
}

// The logged ray of the sample whose hit point is nearest `o`: the ray this one leaves
// (secondary and shadow rays start at their parent's hit, give or take an offset). The latest of
// equally near ones, as a recursive tracer's deepest open ray is the latest.
inline int parent_of(const std::vector<Rec>& recs, const V3& o) {
    int best = -1;
    double best_d = INFINITY;
    for (int i = int(recs.size()) - 1; i >= 0; --i) {
        const Rec& r = recs[size_t(i)];
        if (r.shadow || !r.traced || r.missed) continue;
        double dx = r.point[0] - o[0], dy = r.point[1] - o[1], dz = r.point[2] - o[2];
        double d = dx * dx + dy * dy + dz * dz;
        if (d < best_d) {
            best_d = d;
            best = i;
        }
    }
    return best;
}

inline Sample* active() {
    Sample& s = current();
    return s.active && log().out ? &s : nullptr;
}

inline void start_sample(int x, int y, int index, const V3& o, const V3& d) {
    Sample& s = current();
    Log& l = log();
    if (!s.recs.empty()) {
        std::lock_guard<std::mutex> g(l.gate);
        l.write(s);
    }
    s.active = l.out && l.wanted(x, y, index);
    if (!s.active) return;
    s.x = x;
    s.y = y;
    s.index = index;
    Rec r;
    r.kind = "camera";
    r.origin = o;
    r.direction = d;
    r.awaiting = true;
    s.recs.push_back(r);
}

inline void cast(const char* kind, const V3& o, const V3& d) {
    Sample* s = active();
    if (!s) return;
    // A tracer that logged the hit first: name that ray.
    for (auto it = s->recs.rbegin(); it != s->recs.rend(); ++it)
        if (!it->kind && !it->shadow && it->origin == o && it->direction == d) {
            it->kind = kind;
            return;
        }
    Rec r;
    r.kind = kind;
    r.parent = parent_of(s->recs, o);
    r.origin = o;
    r.direction = d;
    r.awaiting = true;
    s->recs.push_back(r);
}

inline void traced(const V3& o, const V3& d, bool found, const V3& p, const V3& n) {
    Sample* s = active();
    if (!s) return;
    // The ray cast last with these numbers, or else the ray cast last.
    Rec *target = nullptr, *latest = nullptr;
    for (auto it = s->recs.rbegin(); it != s->recs.rend() && !target; ++it) {
        if (!it->awaiting) continue;
        if (!latest) latest = &*it;
        if (it->origin == o && it->direction == d) target = &*it;
    }
    if (!target) target = latest;
    if (!target) {
        Rec r;
        r.parent = parent_of(s->recs, o);
        r.origin = o;
        r.direction = d;
        s->recs.push_back(r);
        target = &s->recs.back();
    }
    target->awaiting = false;
    target->traced = true;
    target->missed = !found;
    if (found) {
        target->point = p;
        target->normal = n;
    }
}

inline void shadow(const V3& o, const V3& d, const V3& light, bool blocked) {
    Sample* s = active();
    if (!s) return;
    // A tracer whose hit() call sits in the nearest-hit search it also runs for shadow rays has
    // just logged this ray as a traced one: it is this shadow ray.
    if (!s->recs.empty() && !s->recs.back().kind && s->recs.back().origin == o && s->recs.back().direction == d)
        s->recs.pop_back();
    Rec r;
    r.kind = "shadow";
    r.shadow = true;
    r.parent = parent_of(s->recs, o);
    r.origin = o;
    r.direction = d;
    r.light = light;
    r.blocked = blocked;
    s->recs.push_back(r);
}

// The colour belongs to the latest ray without one: in a recursive tracer whose every return
// goes through raylog::color, the rays cast below this one have theirs already.
inline void colored(const V3& c) {
    Sample* s = active();
    if (!s) return;
    for (auto it = s->recs.rbegin(); it != s->recs.rend(); ++it)
        if (!it->shadow && !it->has_color) {
            it->has_color = true;
            it->color = c;
            return;
        }
}

}  // namespace detail

/// True when RAYSCOPE_LOG names a log file, read once at start-up.
inline const bool on = detail::env_on();

/// A camera ray for sample `sample` of pixel (x, y), 0-based from the top-left; call it before tracing the ray.
template <class V>
inline void camera(int x, int y, int sample, const V& origin, const V& direction) {
    if (on) detail::start_sample(x, y, sample, detail::xyz(origin), detail::xyz(direction));
}

/// A reflected ray, cast from the hit it leaves; call it before tracing the ray.
template <class V>
inline void reflection(const V& origin, const V& direction) {
    if (on) detail::cast("reflection", detail::xyz(origin), detail::xyz(direction));
}

/// A refracted ray, cast from the hit it leaves; call it before tracing the ray.
template <class V>
inline void refraction(const V& origin, const V& direction) {
    if (on) detail::cast("refraction", detail::xyz(origin), detail::xyz(direction));
}

/// What a traced ray hit: its nearest hit point and normal.
template <class V>
inline void hit(const V& origin, const V& direction, const V& point, const V& normal) {
    if (on) detail::traced(detail::xyz(origin), detail::xyz(direction), true, detail::xyz(point), detail::xyz(normal));
}

/// A traced ray that hit nothing.
template <class V>
inline void miss(const V& origin, const V& direction) {
    if (on) detail::traced(detail::xyz(origin), detail::xyz(direction), false, {}, {});
}

/// A shadow ray toward the light at `light`, and whether something blocked it.
template <class V>
inline void shadow(const V& origin, const V& direction, const V& light, bool blocked) {
    if (on) detail::shadow(detail::xyz(origin), detail::xyz(direction), detail::xyz(light), blocked);
}

/// The colour the ray being traced brings back (linear, before clamping); returns it unchanged.
template <class C>
inline C color(C c) {
    if (on) detail::colored(detail::xyz(c));
    return c;
}

/// Writes every buffered sample and closes the log; also done at exit.
inline void close() {
    if (on) detail::log().close();
}

}  // namespace raylog

#endif
