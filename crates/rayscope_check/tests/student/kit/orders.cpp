// Drives kits/cpp/raylog.hpp through the call orders a tracer may use (see kits.rs,
// `the_kits_work_out_the_tree_whatever_the_call_order`), with std::array vectors and an r, g, b
// colour; the Python and C# twins make the same calls.
//     g++ -std=c++17 -pthread -I kits/cpp -o orders orders.cpp
#include <array>

#include "raylog.hpp"

using A = std::array<double, 3>;

struct Rgb {
    double r, g, b;
};

int main() {
    raylog::camera(1, 2, 3, A{0, 0, 0}, A{0, 0, 1});
    raylog::hit(A{0, 0, 0}, A{0, 0, 1}, A{0, 0, 5}, A{0, 0, -1});
    // The hit logged before the kind.
    raylog::hit(A{0, 0, 4.99999}, A{0, 1, 0}, A{0, 3, 5}, A{0, -1, 0});
    raylog::reflection(A{0, 0, 4.99999}, A{0, 1, 0});
    // A hit() in the nearest-hit search that the shadow test runs too.
    raylog::miss(A{0, 2.99999, 5}, A{1, 0, 0});
    raylog::shadow(A{0, 2.99999, 5}, A{1, 0, 0}, A{4, 3, 5}, false);
    raylog::color(Rgb{0.5, 0.5, 0.5});
    raylog::refraction(A{0, 0, 5.00001}, A{0, 0, 1});
    raylog::miss(A{0, 0, 5.00001}, A{0, 0, 1});
    raylog::color(Rgb{0, 0, 0});
    raylog::color(Rgb{0.25, 0.25, 0.25});
    // A pixel the filter leaves out, then calls after close(): nothing written.
    raylog::camera(0, 0, 0, A{0, 0, 0}, A{0, 0, 1});
    raylog::miss(A{0, 0, 0}, A{0, 0, 1});
    raylog::color(Rgb{1, 1, 1});
    raylog::close();
    raylog::camera(1, 2, 0, A{0, 0, 0}, A{0, 0, 1});
    raylog::miss(A{0, 0, 0}, A{0, 0, 1});
    raylog::close();
}
