# 64-bit ARM cab controllers (Debian arm64): see debian-cross.cmake.
set(OEGW_CROSS_TRIPLET aarch64-linux-gnu)
set(OEGW_CROSS_DEBARCH arm64)
set(OEGW_CROSS_PROCESSOR aarch64)
set(OEGW_CROSS_QEMU qemu-aarch64-static)
include(${CMAKE_CURRENT_LIST_DIR}/debian-cross.cmake)
