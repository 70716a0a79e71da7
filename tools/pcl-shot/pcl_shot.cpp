// PCL reference for Motif's SHOT descriptor (crates/motif-core/src/shot.rs).
//
// Usage: pcl_shot POINTS.xyzn KEYPOINTS.txt RADIUS OUT.peershot [REPEAT]
//   POINTS.xyzn   plain text, one point per line: "x y z nx ny nz" (blank lines and lines starting
//                 with '#' are ignored)
//   KEYPOINTS.txt one 0-based point index per line
//   RADIUS        the support radius (same unit as the points)
//   OUT.peershot  PEERSHOT binary output (see shot.rs): magic "PEERSHOT", u32 count, u32 352, then
//                 per keypoint u32 index, f32 frame[9] (x, y, z axes), f32 descriptor[352]; LE
//   REPEAT        optional: run the computation this many times and report the fastest (default 1)
//
// Runs pcl::SHOTEstimation<PointNormal, PointNormal, SHOT352> single-threaded with the full cloud
// as the search surface and the keypoints as the input cloud; frames come from SHOT352::rf (PCL
// computes them itself with SHOTLocalReferenceFrameEstimation at the same radius). Prints one line
// "pcl_shot: keypoints=N points=M radius=R compute_ms=T ms_per_keypoint=T/N" on stdout; the time
// covers SHOTEstimation::compute only (kd-tree build over the surface included, file IO excluded).

#include <pcl/features/shot.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include <cstring>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace {

[[noreturn]] void die(const std::string& msg) {
    std::cerr << "pcl_shot: " << msg << "\n";
    std::exit(2);
}

bool skip_line(const std::string& line) {
    for (char c : line) {
        if (c == '#') return true;
        if (c != ' ' && c != '\t' && c != '\r') return false;
    }
    return true;
}

void put_u32(std::ofstream& out, std::uint32_t v) {
    unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8),
                          static_cast<unsigned char>(v >> 16), static_cast<unsigned char>(v >> 24)};
    out.write(reinterpret_cast<const char*>(b), 4);
}

void put_f32(std::ofstream& out, float f) {
    std::uint32_t v;
    static_assert(sizeof v == sizeof f, "f32 is 4 bytes");
    std::memcpy(&v, &f, 4);
    put_u32(out, v);
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 5 && argc != 6) {
        die("usage: pcl_shot POINTS.xyzn KEYPOINTS.txt RADIUS OUT.peershot [REPEAT]");
    }
    const double radius = std::atof(argv[3]);
    if (!(radius > 0.0)) die("RADIUS must be a positive number");
    const int repeat = argc == 6 ? std::atoi(argv[5]) : 1;
    if (repeat < 1) die("REPEAT must be at least 1");

    pcl::PointCloud<pcl::PointNormal>::Ptr surface(new pcl::PointCloud<pcl::PointNormal>);
    {
        std::ifstream in(argv[1]);
        if (!in) die(std::string("cannot open ") + argv[1]);
        std::string line;
        std::size_t lineno = 0;
        while (std::getline(in, line)) {
            ++lineno;
            if (skip_line(line)) continue;
            std::istringstream s(line);
            pcl::PointNormal p;
            if (!(s >> p.x >> p.y >> p.z >> p.normal_x >> p.normal_y >> p.normal_z)) {
                die(std::string(argv[1]) + ": line " + std::to_string(lineno) +
                    ": expected 'x y z nx ny nz'");
            }
            p.curvature = 0.0f;
            surface->push_back(p);
        }
    }
    if (surface->empty()) die(std::string(argv[1]) + ": no points");

    std::vector<std::uint32_t> key_index;
    pcl::PointCloud<pcl::PointNormal>::Ptr keys(new pcl::PointCloud<pcl::PointNormal>);
    {
        std::ifstream in(argv[2]);
        if (!in) die(std::string("cannot open ") + argv[2]);
        std::string line;
        std::size_t lineno = 0;
        while (std::getline(in, line)) {
            ++lineno;
            if (skip_line(line)) continue;
            unsigned long long k = 0;
            std::istringstream s(line);
            if (!(s >> k) || k >= surface->size()) {
                die(std::string(argv[2]) + ": line " + std::to_string(lineno) +
                    ": expected a point index below " + std::to_string(surface->size()));
            }
            key_index.push_back(static_cast<std::uint32_t>(k));
            keys->push_back((*surface)[k]);
        }
    }

    pcl::PointCloud<pcl::SHOT352> result;
    double best_ms = 1e300;
    for (int run = 0; run < repeat; ++run) {
        const auto t0 = std::chrono::steady_clock::now();
        pcl::SHOTEstimation<pcl::PointNormal, pcl::PointNormal, pcl::SHOT352> shot;
        pcl::search::KdTree<pcl::PointNormal>::Ptr tree(new pcl::search::KdTree<pcl::PointNormal>);
        shot.setSearchMethod(tree);
        shot.setInputCloud(keys);
        shot.setSearchSurface(surface);
        shot.setInputNormals(surface);
        shot.setRadiusSearch(radius);
        result.clear();
        shot.compute(result);
        const auto t1 = std::chrono::steady_clock::now();
        const double ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
        if (ms < best_ms) best_ms = ms;
    }
    if (result.size() != keys->size()) die("PCL returned a different number of descriptors");

    std::ofstream out(argv[4], std::ios::binary);
    if (!out) die(std::string("cannot create ") + argv[4]);
    out.write("PEERSHOT", 8);
    put_u32(out, static_cast<std::uint32_t>(result.size()));
    put_u32(out, 352);
    for (std::size_t i = 0; i < result.size(); ++i) {
        put_u32(out, key_index[i]);
        for (int k = 0; k < 9; ++k) put_f32(out, result[i].rf[k]);
        for (int k = 0; k < 352; ++k) put_f32(out, result[i].descriptor[k]);
    }
    if (!out) die(std::string("failed writing ") + argv[4]);

    std::printf("pcl_shot: keypoints=%zu points=%zu radius=%g compute_ms=%.3f ms_per_keypoint=%.5f\n",
                keys->size(), surface->size(), radius, best_ms,
                keys->empty() ? 0.0 : best_ms / static_cast<double>(keys->size()));
    return 0;
}
