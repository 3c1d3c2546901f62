// Reads a .vdb with OpenVDB (the C++ library, fully loaded) and writes it again with
// OpenVDB's own writer, COMPRESS_ACTIVE_MASK only, for compare.py to set beside the
// original. Built by run.sh when libopenvdb-dev (with libboost-dev, libimath-dev) is
// installed:  g++ -std=c++17 rewrite.cpp -lopenvdb -ltbb -lImath-3_1
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <iostream>

int main(int argc, char** argv) {
    if (argc != 3) {
        std::cerr << "usage: rewrite IN.vdb OUT.vdb\n";
        return 2;
    }
    openvdb::initialize();
    openvdb::io::File in(argv[1]);
    in.open(/*delayLoad=*/false);
    openvdb::GridPtrVecPtr grids = in.getGrids();
    openvdb::MetaMap::Ptr meta = in.getMetadata();
    in.close();
    openvdb::io::File out(argv[2]);
    out.setCompression(openvdb::io::COMPRESS_ACTIVE_MASK);
    out.write(*grids, *meta);
    out.close();
    return 0;
}
