// Rewrites every grid of an OpenVDB file with the given compression flags (the Python bindings
// always write OpenVDB's default, Blosc + active mask). Built and run by make_vdb_fixtures.py.
// usage: vdb_recompress IN OUT FLAGS   (FLAGS: 0 none, 1 zip, 2 active mask, 4 blosc; or-ed)
#include <openvdb/openvdb.h>
#include <cstdlib>
#include <iostream>

int main(int argc, char** argv) {
    if (argc != 4) {
        std::cerr << "usage: vdb_recompress IN OUT FLAGS\n";
        return 2;
    }
    openvdb::initialize();
    openvdb::io::File in(argv[1]);
    in.open();
    openvdb::GridPtrVecPtr grids = in.getGrids();
    in.close();
    openvdb::io::File out(argv[2]);
    out.setCompression(static_cast<uint32_t>(std::atoi(argv[3])));
    out.write(*grids);
    out.close();
    return 0;
}
