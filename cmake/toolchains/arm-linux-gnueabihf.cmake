# 32-bit ARM cab controllers, ARMv7 hard-float (Debian armhf): see debian-cross.cmake.
set(OEGW_CROSS_TRIPLET arm-linux-gnueabihf)
set(OEGW_CROSS_DEBARCH armhf)
set(OEGW_CROSS_PROCESSOR armv7l)
set(OEGW_CROSS_QEMU qemu-arm-static)
include(${CMAKE_CURRENT_LIST_DIR}/debian-cross.cmake)
