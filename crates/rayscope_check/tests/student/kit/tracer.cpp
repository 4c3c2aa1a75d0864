// A small student-style ray tracer (stage 2 of the course, rows shared among std::threads) with
// rayscope's kit, kits/cpp/raylog.hpp, added as a student adds it: the #include and the lines
// that call raylog. `--bug NAME` switches on one mistake:
//   shadow-no-offset   shadow rays start exactly on the surface
//   reflect-no-2       the reflection formula without its factor 2: d - (d.n) n
//   refraction-normal  leaving glass, the refraction uses the outward normal (not flipped)
// Build: g++ -O2 -std=c++17 -pthread -I kits/cpp -o tracer tracer.cpp
// Usage: tracer -f scene.txt [-w 400] [-h 400] [-x 1] [--threads 4] [--bug NAME]
#include <atomic>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "raylog.hpp"

struct Vec3 {
    double x = 0, y = 0, z = 0;
};
static Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
static Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
static Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
static Vec3 operator*(Vec3 a, double k) { return {a.x * k, a.y * k, a.z * k}; }
static Vec3 mul(Vec3 a, Vec3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
static double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
static Vec3 normalize(Vec3 a) { return a * (1 / std::sqrt(dot(a, a))); }

struct Material {
    std::string type;
    Vec3 color;
    double index;
};

struct Hit {
    double t;
    Vec3 p, n;
};

struct Entity {
    enum { SPHERE, PLANE, TRIANGLE } kind;
    Vec3 a, e1, e2, n;  // sphere: centre a, radius r; plane: point a, normal n; triangle: v0 a
    double r = 0;
    const Material* m;

    bool intersect(Vec3 o, Vec3 d, Hit& h) const {
        double t;
        if (kind == SPHERE) {
            Vec3 oc = o - a;
            double b = dot(oc, d), disc = b * b - (dot(oc, oc) - r * r);
            if (disc < 0) return false;
            double s = std::sqrt(disc);
            t = -b - s > 0 ? -b - s : -b + s;
            if (t <= 0) return false;
            h = {t, o + d * t, normalize(o + d * t - a)};
            return true;
        }
        if (kind == PLANE) {
            double den = dot(n, d);
            if (den == 0) return false;
            t = dot(a - o, n) / den;
        } else {
            Vec3 p = cross(d, e2);
            double det = dot(e1, p);
            if (std::fabs(det) < 1e-12) return false;
            Vec3 s = o - a;
            double u = dot(s, p) / det;
            if (u < 0 || u > 1) return false;
            Vec3 q = cross(s, e1);
            double v = dot(d, q) / det;
            if (v < 0 || u + v > 1) return false;
            t = dot(e2, q) / det;
        }
        if (t <= 0) return false;
        h = {t, o + d * t, n};
        return true;
    }
};

struct Light {
    Vec3 pos, color;
};

static const double EPS = 1e-5;
static const int MAX_DEPTH = 8;

struct Tracer {
    std::vector<Entity> entities;
    std::vector<Light> lights;
    std::map<std::string, std::unique_ptr<Material>> materials;
    std::string bug = "none";

    const Entity* closest(Vec3 o, Vec3 d, Hit& best) const {
        const Entity* found = nullptr;
        Hit h;
        for (const Entity& e : entities)
            if (e.intersect(o, d, h) && (!found || h.t < best.t)) {
                best = h;
                found = &e;
            }
        return found;
    }

    Vec3 trace(Vec3 o, Vec3 d, int depth) const {
        Hit h;
        const Entity* e = closest(o, d, h);
        if (!e) {
            raylog::miss(o, d);
            return raylog::color(Vec3{0, 0, 0});
        }
        raylog::hit(o, d, h.p, h.n);
        return raylog::color(shade(d, h, *e->m, depth));
    }

    Vec3 shade(Vec3 d, const Hit& h, const Material& m, int depth) const {
        bool front = dot(h.n, d) < 0;
        Vec3 nf = front ? h.n : -h.n;
        if (m.type == "Reflective") return depth >= MAX_DEPTH ? Vec3{} : trace_reflection(d, h.p, nf, depth);
        if (m.type == "Refractive") return depth >= MAX_DEPTH ? Vec3{} : glass(d, h, nf, front, m.index, depth);
        Vec3 col;
        for (const Light& l : lights) {
            Vec3 so = bug == "shadow-no-offset" ? h.p : h.p + nf * EPS;
            Vec3 to = l.pos - so;
            double dist = std::sqrt(dot(to, to));
            Vec3 ldir = to * (1 / dist);
            Hit b;
            bool blocked = closest(so, ldir, b) && b.t < dist;
            raylog::shadow(so, ldir, l.pos, blocked);
            if (!blocked) col = col + mul(m.color, l.color) * std::max(0.0, dot(nf, ldir));
        }
        return col;
    }

    Vec3 trace_reflection(Vec3 d, Vec3 p, Vec3 nf, int depth) const {
        double k = bug == "reflect-no-2" ? 1 : 2;
        Vec3 ro = p + nf * EPS, rd = normalize(d - nf * (k * dot(d, nf)));
        raylog::reflection(ro, rd);
        return trace(ro, rd, depth + 1);
    }

    Vec3 glass(Vec3 d, const Hit& h, Vec3 nf, bool front, double index, int depth) const {
        double n1 = front ? 1 : index, n2 = front ? index : 1;
        Vec3 nn = bug == "refraction-normal" ? h.n : nf;
        double eta = n1 / n2, cosi = -dot(d, nn);
        double k = 1 - eta * eta * (1 - cosi * cosi);
        Vec3 refl = trace_reflection(d, h.p, nf, depth);
        if (k < 0) return refl;
        double ci = std::fabs(cosi), ct = std::sqrt(k);
        double rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct), rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
        double kr = 0.5 * (rs * rs + rp * rp);
        Vec3 to = h.p - nn * EPS, td = normalize(d * eta + nn * (eta * cosi - ct));
        raylog::refraction(to, td);
        return refl * kr + trace(to, td, depth + 1) * (1 - kr);
    }
};

static void load(Tracer& tr, const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error("cannot read " + path);
    std::string line;
    std::regex sep("[\\s,\"()]+");
    while (std::getline(in, line)) {
        std::vector<std::string> t;
        for (std::sregex_token_iterator it(line.begin(), line.end(), sep, -1), end; it != end; ++it)
            if (!it->str().empty()) t.push_back(*it);
        if (t.empty() || t[0][0] == '#') continue;
        auto v = [&](size_t i) { return Vec3{std::stod(t.at(i)), std::stod(t.at(i + 1)), std::stod(t.at(i + 2))}; };
        Entity e{};
        if (t[0] == "Material") {
            tr.materials[t.at(1)].reset(new Material{t.at(2), v(3), std::stod(t.at(6))});
            continue;
        } else if (t[0] == "PointLight") {
            tr.lights.push_back({v(2), v(5)});
            continue;
        } else if (t[0] == "Plane") {
            e.kind = Entity::PLANE;
            e.a = v(2);
            e.n = normalize(v(5));
            e.m = tr.materials.at(t.at(8)).get();
        } else if (t[0] == "Sphere") {
            e.kind = Entity::SPHERE;
            e.a = v(2);
            e.r = std::stod(t.at(5));
            e.m = tr.materials.at(t.at(6)).get();
        } else if (t[0] == "Triangle") {
            e.kind = Entity::TRIANGLE;
            e.a = v(2);
            e.e1 = v(5) - e.a;
            e.e2 = v(8) - e.a;
            e.n = normalize(cross(e.e1, e.e2));
            e.m = tr.materials.at(t.at(11)).get();
        } else {
            throw std::runtime_error(path + ": unsupported command " + t[0]);
        }
        tr.entities.push_back(e);
    }
}

int main(int argc, char** argv) {
    std::string scene;
    int w = 400, h = 400, n = 1, threads = 4;
    Tracer tr;
    for (int i = 1; i + 1 < argc; i += 2) {
        std::string a = argv[i], val = argv[i + 1];
        if (a == "-f") scene = val;
        else if (a == "-w") w = std::stoi(val);
        else if (a == "-h") h = std::stoi(val);
        else if (a == "-x") n = std::stoi(val);
        else if (a == "--threads") threads = std::stoi(val);
        else if (a == "--bug") tr.bug = val;
        else {
            std::cerr << "unknown argument " << a << "\n";
            return 2;
        }
    }
    if (scene.empty()) {
        std::cerr << "usage: tracer -f scene.txt [-w W] [-h H] [-x N] [--threads T] [--bug NAME]\n";
        return 2;
    }
    load(tr, scene);
    double half = std::tan(M_PI / 6);
    std::atomic<int> next_row{0};
    auto work = [&]() {
        for (int y; (y = next_row++) < h;)
            for (int x = 0; x < w; ++x)
                for (int j = 0; j < n; ++j)
                    for (int i = 0; i < n; ++i) {
                        double u = (x + (i + 0.5) / n) / w, v = (y + (j + 0.5) / n) / h;
                        Vec3 o{0, 0, 0}, d = normalize({(2 * u - 1) * half, (1 - 2 * v) * half * h / w, 1});
                        raylog::camera(x, y, j * n + i, o, d);
                        tr.trace(o, d, 0);
                    }
    };
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(work);
    for (std::thread& t : pool) t.join();
    return 0;
}
