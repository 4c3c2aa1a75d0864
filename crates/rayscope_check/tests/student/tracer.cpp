// A student-style Whitted ray tracer for the course's scene format, in C++17 with the standard
// library only, for rayscope's `check` tests and benchmark. Build: g++ -O2 -std=c++17 tracer.cpp
//
// It renders stage 2 as the course describes it (point lights with shadow rays, mirrors, Fresnel
// glass with total internal reflection, an N x N sub-pixel grid, OBJ models shaded with
// interpolated vertex normals), or stage 1 with `--stage 1` (the closest hit's material colour,
// one ray through each pixel centre), and logs every ray it casts in rayscope's JSON Lines
// format, each with the colour it brought back (shadow rays excepted). A sample's rays are
// written together once the sample is traced. `--bug NAME` switches on one realistic mistake:
//
//   shadow-no-offset   shadow rays start exactly on the surface (no offset)
//   one-sided          triangles (the OBJ model's too) are one-sided: back faces culled
//   no-fresnel         glass brings back its refracted colour only (kr = 0, still casting the
//                      reflection)
//   obj-flat-normals   OBJ faces shaded with their flat normal, the vn normals ignored
//   obj-no-z-flip      OBJ positions and normals used as written, z not negated (the model is
//                      mirrored front to back)
//   parallelogram      the triangle test checks u <= 1 and v <= 1 but not u + v <= 1, so every
//                      triangle is the parallelogram it spans (no catalogue has it)
//
// Usage: tracer -f scene.txt [-w 400] [-h 400] [-x 1] [--stage 2] [--region x0,y0,x1,y1]
//        [--bug NAME] [--log rays.jsonl] [--image out.ppm] [--no-colors]

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

struct Vec3 {
    double x = 0, y = 0, z = 0;
};
static Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
static Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
static Vec3 operator*(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
static Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
static Vec3 hadamard(Vec3 a, Vec3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
static double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static Vec3 cross(Vec3 a, Vec3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
static double length(Vec3 a) { return std::sqrt(dot(a, a)); }
static Vec3 normalize(Vec3 a) { return a * (1.0 / length(a)); }

static const double EPS = 1e-5;
static const int MAX_DEPTH = 8;

static std::string bug = "none";

[[noreturn]] static void die(const std::string& msg) {
    std::fprintf(stderr, "tracer: %s\n", msg.c_str());
    std::exit(2);
}

struct Material {
    std::string type;
    Vec3 color;
    double value = 1;
};

struct Light {
    std::string name;
    Vec3 pos, color;
};

struct Triangle {
    Vec3 v0, e1, e2, n;  // n: unit (v1 - v0) x (v2 - v0)
    bool smooth = false;
    Vec3 n0, n1, n2;  // unit vertex normals at v0, v1, v2
};

// A bounding-volume hierarchy over a mesh's triangles.
struct Node {
    Vec3 lo, hi;
    int left = -1, right = -1;  // children, or -1 for a leaf
    int first = 0, count = 0;   // a leaf's triangles in `order`
};

struct Entity {
    std::string name;
    enum Kind { PLANE, SPHERE, TRIANGLE, MESH } kind;
    const Material* mat;
    Vec3 p, n;          // plane
    Vec3 c;             // sphere
    double r = 0;       // sphere
    std::vector<Triangle> tris;  // triangle (one) or mesh
    std::vector<Node> nodes;
    std::vector<int> order;
};

struct Hit {
    double t;
    const Entity* e;
    const Triangle* tri;
    double u, v;
};

// --- intersection ---------------------------------------------------------------------------

// Moller-Trumbore; det > 0 on the front face. Nearest t in (0, tmax), with the barycentrics.
static bool hit_triangle(const Triangle& tr, Vec3 o, Vec3 d, double tmax, double& t, double& u, double& v) {
    Vec3 p = cross(d, tr.e2);
    double det = dot(tr.e1, p);
    if (bug == "one-sided") {
        if (det < 1e-12) return false;
    } else if (std::fabs(det) < 1e-12) {
        return false;
    }
    double inv = 1.0 / det;
    Vec3 s = o - tr.v0;
    u = dot(s, p) * inv;
    if (u < 0 || u > 1) return false;
    Vec3 q = cross(s, tr.e1);
    v = dot(d, q) * inv;
    if (v < 0 || (bug == "parallelogram" ? v > 1 : u + v > 1)) return false;
    t = dot(tr.e2, q) * inv;
    return t > 0 && t < tmax;
}

static bool hit_box(const Node& n, Vec3 o, Vec3 inv, double tmax) {
    double t0 = 0, t1 = tmax;
    const double os[3] = {o.x, o.y, o.z}, is[3] = {inv.x, inv.y, inv.z};
    const double lo[3] = {n.lo.x, n.lo.y, n.lo.z}, hi[3] = {n.hi.x, n.hi.y, n.hi.z};
    for (int a = 0; a < 3; ++a) {
        double ta = (lo[a] - os[a]) * is[a], tb = (hi[a] - os[a]) * is[a];
        if (ta > tb) std::swap(ta, tb);
        // A little slack so that rounding never loses a triangle lying on the box's face.
        ta -= 1e-9 * (std::fabs(ta) + 1);
        tb += 1e-9 * (std::fabs(tb) + 1);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

// The entity's nearest hit with t in (0, tmax); `best` is updated when one is nearer.
static void intersect(const Entity& e, Vec3 o, Vec3 d, Hit& best) {
    double tmax = best.t;
    switch (e.kind) {
        case Entity::PLANE: {
            double den = dot(e.n, d);
            if (den == 0) return;
            double t = dot(e.p - o, e.n) / den;
            if (t > 0 && t < tmax) best = {t, &e, nullptr, 0, 0};
            return;
        }
        case Entity::SPHERE: {
            Vec3 oc = o - e.c;
            double b = dot(oc, d) / dot(d, d);
            double c = (dot(oc, oc) - e.r * e.r) / dot(d, d);
            double disc = b * b - c;
            if (disc < 0) return;
            double s = std::sqrt(disc);
            for (double t : {-b - s, -b + s}) {
                if (t > 0) {
                    if (t < tmax) best = {t, &e, nullptr, 0, 0};
                    return;
                }
            }
            return;
        }
        case Entity::TRIANGLE: {
            double t, u, v;
            if (hit_triangle(e.tris[0], o, d, tmax, t, u, v)) best = {t, &e, &e.tris[0], u, v};
            return;
        }
        case Entity::MESH: {
            Vec3 inv = {1.0 / d.x, 1.0 / d.y, 1.0 / d.z};
            int stack[64];
            int top = 0;
            stack[top++] = 0;
            while (top > 0) {
                const Node& n = e.nodes[stack[--top]];
                if (!hit_box(n, o, inv, best.t)) continue;
                if (n.left < 0) {
                    for (int i = n.first; i < n.first + n.count; ++i) {
                        const Triangle& tr = e.tris[e.order[i]];
                        double t, u, v;
                        if (hit_triangle(tr, o, d, best.t, t, u, v)) best = {t, &e, &tr, u, v};
                    }
                } else {
                    stack[top++] = n.left;
                    stack[top++] = n.right;
                }
            }
            return;
        }
    }
}

static int build(Entity& e, int first, int count) {
    Node n;
    Vec3 big = {1e300, 1e300, 1e300};
    n.lo = big;
    n.hi = -big;
    Vec3 clo = big, chi = -big;
    auto grow = [](Vec3& lo, Vec3& hi, Vec3 p) {
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
    };
    auto centre = [&](int i) {
        const Triangle& t = e.tris[i];
        return t.v0 + (t.e1 + t.e2) * (1.0 / 3.0);
    };
    for (int i = first; i < first + count; ++i) {
        const Triangle& t = e.tris[e.order[i]];
        grow(n.lo, n.hi, t.v0);
        grow(n.lo, n.hi, t.v0 + t.e1);
        grow(n.lo, n.hi, t.v0 + t.e2);
        grow(clo, chi, centre(e.order[i]));
    }
    int idx = (int)e.nodes.size();
    e.nodes.push_back(n);
    if (count <= 4) {
        e.nodes[idx].first = first;
        e.nodes[idx].count = count;
        return idx;
    }
    Vec3 ext = chi - clo;
    int axis = ext.x > ext.y ? (ext.x > ext.z ? 0 : 2) : (ext.y > ext.z ? 1 : 2);
    auto key = [&](int i) {
        Vec3 c = centre(i);
        return axis == 0 ? c.x : axis == 1 ? c.y : c.z;
    };
    int mid = first + count / 2;
    std::nth_element(e.order.begin() + first, e.order.begin() + mid, e.order.begin() + first + count,
                     [&](int a, int b) { return key(a) < key(b); });
    int l = build(e, first, mid - first);
    int r = build(e, mid, first + count - mid);
    e.nodes[idx].left = l;
    e.nodes[idx].right = r;
    return idx;
}

// --- scene ----------------------------------------------------------------------------------

struct Scene {
    std::map<std::string, Material> materials;
    std::vector<Light> lights;
    std::vector<Entity> entities;
};

static std::vector<std::string> tokens(const std::string& line) {
    std::vector<std::string> out;
    std::string cur;
    for (char ch : line) {
        if (std::isspace((unsigned char)ch) || ch == ',' || ch == '"' || ch == '(' || ch == ')') {
            if (!cur.empty()) out.push_back(cur);
            cur.clear();
        } else {
            cur += ch;
        }
    }
    if (!cur.empty()) out.push_back(cur);
    return out;
}

static Triangle make_triangle(Vec3 v0, Vec3 v1, Vec3 v2) {
    Triangle t;
    t.v0 = v0;
    t.e1 = v1 - v0;
    t.e2 = v2 - v0;
    t.n = normalize(cross(t.e1, t.e2));
    return t;
}

// The OBJ file: relative to the working directory, then to the scene's folder and its ancestors.
static fs::path find_obj(const std::string& name, const fs::path& scene) {
    if (fs::exists(name)) return name;
    for (fs::path dir = fs::absolute(scene).parent_path();; dir = dir.parent_path()) {
        if (fs::exists(dir / name)) return dir / name;
        if (dir == dir.parent_path()) break;
    }
    die("OBJ file not found: " + name);
}

// A 1-based (or negative, relative) OBJ index into a list of `count`.
static int obj_index(const std::string& s, size_t count) {
    long i = std::stol(s);
    long k = i < 0 ? (long)count + i : i - 1;
    if (k < 0 || k >= (long)count) die("OBJ index out of range: " + s);
    return (int)k;
}

static void load_obj(Entity& e, const fs::path& path, Vec3 offset, double scale) {
    std::ifstream f(path);
    if (!f) die("cannot read " + path.string());
    bool flip = bug != "obj-no-z-flip";
    std::vector<Vec3> pos, nor;
    std::string line;
    while (std::getline(f, line)) {
        std::istringstream ss(line);
        std::string cmd;
        ss >> cmd;
        if (cmd == "v") {
            Vec3 p;
            ss >> p.x >> p.y >> p.z;
            pos.push_back({scale * p.x + offset.x, scale * p.y + offset.y,
                           (flip ? -scale * p.z : scale * p.z) + offset.z});
        } else if (cmd == "vn") {
            Vec3 n;
            ss >> n.x >> n.y >> n.z;
            if (flip) n.z = -n.z;
            nor.push_back(normalize(n));
        } else if (cmd == "f") {
            std::vector<int> vi, ni;
            std::string corner;
            bool all_normals = true;
            while (ss >> corner) {
                // v, v/vt, v//vn or v/vt/vn
                size_t a = corner.find('/');
                vi.push_back(obj_index(corner.substr(0, a), pos.size()));
                size_t b = a == std::string::npos ? a : corner.find('/', a + 1);
                if (b != std::string::npos && b + 1 < corner.size()) {
                    ni.push_back(obj_index(corner.substr(b + 1), nor.size()));
                } else {
                    all_normals = false;
                    ni.push_back(-1);
                }
            }
            if (vi.size() < 3) die("OBJ face with fewer than 3 vertices");
            for (size_t k = 1; k + 1 < vi.size(); ++k) {
                Triangle t = make_triangle(pos[vi[0]], pos[vi[k]], pos[vi[k + 1]]);
                if (all_normals && bug != "obj-flat-normals") {
                    t.smooth = true;
                    t.n0 = nor[ni[0]];
                    t.n1 = nor[ni[k]];
                    t.n2 = nor[ni[k + 1]];
                }
                e.tris.push_back(t);
            }
        }
    }
    if (e.tris.empty()) die("OBJ file without faces: " + path.string());
    e.order.resize(e.tris.size());
    for (size_t i = 0; i < e.order.size(); ++i) e.order[i] = (int)i;
    build(e, 0, (int)e.tris.size());
}

static Scene load_scene(const std::string& path) {
    std::ifstream f(path);
    if (!f) die("cannot read " + path);
    Scene sc;
    std::string line;
    int lineno = 0;
    // Entities refer to materials by address, so materials are never added after the first one.
    std::vector<std::vector<std::string>> later;
    while (std::getline(f, line)) {
        ++lineno;
        auto tok = tokens(line);
        if (tok.empty() || tok[0][0] == '#') continue;
        auto num = [&](size_t i) {
            if (i >= tok.size()) die("line " + std::to_string(lineno) + ": too few values");
            return std::stod(tok[i]);
        };
        auto vec = [&](size_t i) { return Vec3{num(i), num(i + 1), num(i + 2)}; };
        const std::string& cmd = tok[0];
        if (cmd == "Material") {
            sc.materials[tok.at(1)] = {tok.at(2), vec(3), num(6)};
        } else if (cmd == "PointLight") {
            sc.lights.push_back({tok.at(1), vec(2), vec(5)});
        } else if (cmd == "Plane" || cmd == "Sphere" || cmd == "Triangle" || cmd == "ObjModel") {
            later.push_back(tok);
        } else {
            die("line " + std::to_string(lineno) + ": unsupported command " + cmd);
        }
    }
    auto mat = [&](const std::string& name) {
        auto it = sc.materials.find(name);
        if (it == sc.materials.end()) die("undefined material " + name);
        return &it->second;
    };
    sc.entities.reserve(later.size());
    for (auto& tok : later) {
        auto num = [&](size_t i) { return std::stod(tok.at(i)); };
        auto vec = [&](size_t i) { return Vec3{num(i), num(i + 1), num(i + 2)}; };
        Entity e;
        e.name = tok.at(1);
        if (tok[0] == "Plane") {
            e.kind = Entity::PLANE;
            e.p = vec(2);
            e.n = normalize(vec(5));
            e.mat = mat(tok.at(8));
        } else if (tok[0] == "Sphere") {
            e.kind = Entity::SPHERE;
            e.c = vec(2);
            e.r = num(5);
            e.mat = mat(tok.at(6));
        } else if (tok[0] == "Triangle") {
            e.kind = Entity::TRIANGLE;
            e.tris.push_back(make_triangle(vec(2), vec(5), vec(8)));
            e.mat = mat(tok.at(11));
        } else {
            e.kind = Entity::MESH;
            e.mat = mat(tok.at(7));
            load_obj(e, find_obj(tok.at(2), path), vec(3), num(6));
        }
        sc.entities.push_back(std::move(e));
    }
    return sc;
}

// --- logging --------------------------------------------------------------------------------

// One logged ray; written once its sample is traced, when its colour is known.
struct Record {
    long long id, parent;  // parent -1: a camera ray
    const char* kind;
    Vec3 o, d;
    bool shadow = false;
    bool hit = false;
    double t = 0;
    Vec3 p, n;
    const char* entity = nullptr;
    const char* light = nullptr;    // shadow rays
    const char* blocker = nullptr;  // shadow rays: nullptr when the light is reached
    bool has_color = false;
    Vec3 color;

    Record(long long id, long long parent, const char* kind, Vec3 o, Vec3 d)
        : id(id), parent(parent), kind(kind), o(o), d(d) {}
};

static FILE* rays_out = nullptr;
static bool log_colors = true;
static std::vector<Record> pending;
static long long next_id = 0;
static int cur_x, cur_y, cur_sample;

static void flush_sample() {
    if (!rays_out) return;
    for (const Record& r : pending) {
        std::fprintf(rays_out, "{\"pixel\":[%d,%d],\"sample\":%d,\"id\":%lld,", cur_x, cur_y, cur_sample, r.id);
        if (r.parent < 0)
            std::fputs("\"parent\":null,", rays_out);
        else
            std::fprintf(rays_out, "\"parent\":%lld,", r.parent);
        std::fprintf(rays_out, "\"kind\":\"%s\",\"origin\":[%.9g,%.9g,%.9g],\"direction\":[%.9g,%.9g,%.9g],", r.kind,
                     r.o.x, r.o.y, r.o.z, r.d.x, r.d.y, r.d.z);
        if (r.shadow) {
            std::fprintf(rays_out, "\"light\":\"%s\",\"blocked_by\":", r.light);
            if (r.blocker)
                std::fprintf(rays_out, "\"%s\"}\n", r.blocker);
            else
                std::fputs("null}\n", rays_out);
            continue;
        }
        if (r.hit)
            std::fprintf(rays_out,
                         "\"hit\":{\"t\":%.9g,\"point\":[%.9g,%.9g,%.9g],\"normal\":[%.9g,%.9g,%.9g],"
                         "\"entity\":\"%s\"}",
                         r.t, r.p.x, r.p.y, r.p.z, r.n.x, r.n.y, r.n.z, r.entity);
        else
            std::fputs("\"hit\":null", rays_out);
        if (log_colors && r.has_color)
            std::fprintf(rays_out, ",\"color\":[%.9g,%.9g,%.9g]}\n", r.color.x, r.color.y, r.color.z);
        else
            std::fputs("}\n", rays_out);
    }
    pending.clear();
}

// --- shading --------------------------------------------------------------------------------

struct Tracer {
    const Scene& sc;
    int stage = 2;

    Hit closest(Vec3 o, Vec3 d, double tmax = 1e300) const {
        Hit best{tmax, nullptr, nullptr, 0, 0};
        for (const Entity& e : sc.entities) intersect(e, o, d, best);
        return best;
    }

    // Logs a ray and returns its index in `pending` (its colour is filled in later).
    size_t emit(Record r) {
        if (!rays_out) return 0;
        pending.push_back(r);
        return pending.size() - 1;
    }

    Vec3 colored(size_t rec, Vec3 c) {
        if (rays_out) {
            pending[rec].has_color = true;
            pending[rec].color = c;
        }
        return c;
    }

    Vec3 trace(Vec3 o, Vec3 d, int depth, long long parent, const char* kind) {
        long long id = ++next_id;
        Hit h = closest(o, d);
        Record rec{id, parent, kind, o, d};
        if (!h.e) {
            size_t ri = emit(rec);
            return colored(ri, {0, 0, 0});
        }
        const Entity& e = *h.e;
        Vec3 p = o + d * h.t;
        // The surface's own normal (outward; (v1 - v0) x (v2 - v0) for triangles).
        Vec3 n;
        if (e.kind == Entity::PLANE)
            n = e.n;
        else if (e.kind == Entity::SPHERE)
            n = normalize(p - e.c);
        else
            n = h.tri->n;
        bool front = dot(n, d) < 0;
        Vec3 nf = front ? n : -n;
        // Smooth shading: the interpolated vertex normal, on the side of the face the ray hit.
        Vec3 ns = nf;
        if (h.tri && h.tri->smooth) {
            const Triangle& tr = *h.tri;
            Vec3 s = normalize(tr.n0 * (1 - h.u - h.v) + tr.n1 * h.u + tr.n2 * h.v);
            ns = dot(s, nf) < 0 ? -s : s;
        }
        rec.hit = true;
        rec.t = h.t;
        rec.p = p;
        rec.n = ns;
        rec.entity = e.name.c_str();
        size_t ri = emit(rec);
        const Material& m = *e.mat;
        if (stage == 1) return colored(ri, m.color);
        if (m.type != "Reflective" && m.type != "Refractive") return colored(ri, diffuse(p, nf, ns, m, id));
        if (depth >= MAX_DEPTH) return colored(ri, {0, 0, 0});
        Vec3 r = normalize(d - nf * (2 * dot(d, nf)));
        if (m.type == "Reflective") return colored(ri, trace(p + nf * EPS, r, depth + 1, id, "reflection"));
        return colored(ri, glass(d, p, nf, front, m, depth, id, r));
    }

    // nf: the face's normal facing the ray (shadow rays leave along it); ns: the shading normal.
    Vec3 diffuse(Vec3 p, Vec3 nf, Vec3 ns, const Material& m, long long id) {
        Vec3 col{0, 0, 0};
        for (const Light& l : sc.lights) {
            Vec3 so = bug == "shadow-no-offset" ? p : p + nf * EPS;
            Vec3 to = l.pos - so;
            double dist = length(to);
            Vec3 ldir = to * (1.0 / dist);
            Hit b = closest(so, ldir, dist);
            Record rec{++next_id, id, "shadow", so, ldir};
            rec.shadow = true;
            rec.light = l.name.c_str();
            rec.blocker = b.e ? b.e->name.c_str() : nullptr;
            emit(rec);
            if (!b.e) col = col + hadamard(m.color, l.color) * std::max(0.0, dot(ns, ldir));
        }
        return col;
    }

    Vec3 glass(Vec3 d, Vec3 p, Vec3 nf, bool front, const Material& m, int depth, long long id, Vec3 r) {
        double n1 = front ? 1.0 : m.value, n2 = front ? m.value : 1.0;
        double eta = n1 / n2;
        double cosi = -dot(d, nf);
        double k = 1 - eta * eta * (1 - cosi * cosi);
        double kr;
        if (k < 0) {
            kr = 1;
        } else if (bug == "no-fresnel") {
            kr = 0;
        } else {
            double ct = std::sqrt(k);
            double rs = (n1 * cosi - n2 * ct) / (n1 * cosi + n2 * ct);
            double rp = (n2 * cosi - n1 * ct) / (n2 * cosi + n1 * ct);
            kr = 0.5 * (rs * rs + rp * rp);
        }
        Vec3 col = trace(p + nf * EPS, r, depth + 1, id, "reflection") * kr;
        if (k < 0) return col;
        Vec3 tdir = normalize(d * eta + nf * (eta * cosi - std::sqrt(k)));
        return col + trace(p - nf * EPS, tdir, depth + 1, id, "refraction") * (1 - kr);
    }
};

int main(int argc, char** argv) {
    std::string scene_path, log_path = "-", image_path, region;
    int w = 400, h = 400, n = 1, stage = 2;
    for (int i = 1; i < argc; ++i) {
        std::string a = argv[i];
        auto val = [&]() -> std::string {
            if (i + 1 >= argc) die("missing value after " + a);
            return argv[++i];
        };
        if (a == "-f")
            scene_path = val();
        else if (a == "-w")
            w = std::stoi(val());
        else if (a == "-h")
            h = std::stoi(val());
        else if (a == "-x")
            n = std::stoi(val());
        else if (a == "--stage")
            stage = std::stoi(val());
        else if (a == "--region")
            region = val();
        else if (a == "--bug")
            bug = val();
        else if (a == "--log")
            log_path = val();
        else if (a == "--image")
            image_path = val();
        else if (a == "--no-colors")
            log_colors = false;
        else
            die("unknown argument " + a);
    }
    static const char* bugs[] = {"none", "shadow-no-offset", "one-sided", "no-fresnel", "obj-flat-normals",
                                 "obj-no-z-flip", "parallelogram"};
    if (std::find_if(std::begin(bugs), std::end(bugs), [](const char* b) { return bug == b; }) == std::end(bugs))
        die("unknown bug " + bug);
    if (scene_path.empty()) die("-f scene.txt is required");
    if (w < 1 || h < 1 || n < 1 || (stage != 1 && stage != 2)) die("bad -w, -h, -x or --stage");
    int x0 = 0, y0 = 0, x1 = w, y1 = h;
    if (!region.empty() && std::sscanf(region.c_str(), "%d,%d,%d,%d", &x0, &y0, &x1, &y1) != 4)
        die("--region x0,y0,x1,y1");
    Scene sc = load_scene(scene_path);
    if (log_path != "") {
        rays_out = log_path == "-" ? stdout : std::fopen(log_path.c_str(), "w");
        if (!rays_out) die("cannot write " + log_path);
        static char buf[1 << 20];
        std::setvbuf(rays_out, buf, _IOFBF, sizeof buf);
    }
    Tracer tr{sc, stage};
    // Stage 1: one ray through each pixel centre, whatever -x says.
    int grid = stage == 1 ? 1 : n;
    const double pi = 3.14159265358979323846;
    double hx = std::tan(60.0 * pi / 180.0 / 2), hy = hx * h / w;
    std::vector<Vec3> image;
    for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) {
            Vec3 total{0, 0, 0};
            for (int j = 0; j < grid; ++j) {
                for (int i = 0; i < grid; ++i) {
                    cur_x = x;
                    cur_y = y;
                    cur_sample = j * grid + i;
                    double u = (x + (i + 0.5) / grid) / w, v = (y + (j + 0.5) / grid) / h;
                    Vec3 d = normalize({(2 * u - 1) * hx, (1 - 2 * v) * hy, 1});
                    total = total + tr.trace({0, 0, 0}, d, 0, -1, "camera");
                    flush_sample();
                }
            }
            image.push_back(total * (1.0 / (grid * grid)));
        }
    }
    if (rays_out && rays_out != stdout) std::fclose(rays_out);
    if (rays_out == stdout) std::fflush(stdout);
    if (!image_path.empty()) {
        FILE* f = std::fopen(image_path.c_str(), "w");
        if (!f) die("cannot write " + image_path);
        std::fprintf(f, "P3\n%d %d\n255\n", x1 - x0, y1 - y0);
        for (const Vec3& c : image)
            std::fprintf(f, "%d %d %d\n", (int)(std::min(c.x, 1.0) * 255), (int)(std::min(c.y, 1.0) * 255),
                         (int)(std::min(c.z, 1.0) * 255));
        std::fclose(f);
    }
    return 0;
}
