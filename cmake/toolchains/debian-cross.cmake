# Cross-building oegw for a cab controller with Debian's cross compilers (crossbuild-essential-*)
# against a sysroot of the target's Debian library packages (scripts/cross-sysroot.sh makes it).
# Included by the per-target toolchain files beside this one, which set:
#   OEGW_CROSS_TRIPLET   GNU triplet of the compilers (aarch64-linux-gnu, arm-linux-gnueabihf)
#   OEGW_CROSS_DEBARCH   Debian architecture (arm64, armhf): the sysroot's and the package's
#   OEGW_CROSS_PROCESSOR CMAKE_SYSTEM_PROCESSOR
#   OEGW_CROSS_QEMU      qemu-user program that runs the target's binaries here (qemu-user-static)
# The sysroot: -DOEGW_SYSROOT=..., else $OEGW_SYSROOT, else /var/cache/oegw-cross/sysroot-<arch>.
# docs/guides/build-and-package.md#building-for-the-cab-controller.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR ${OEGW_CROSS_PROCESSOR})

if(NOT OEGW_SYSROOT)
  if(DEFINED ENV{OEGW_SYSROOT})
    set(OEGW_SYSROOT "$ENV{OEGW_SYSROOT}")
  else()
    set(OEGW_SYSROOT "/var/cache/oegw-cross/sysroot-${OEGW_CROSS_DEBARCH}")
  endif()
endif()
if(NOT EXISTS "${OEGW_SYSROOT}/usr/include/${OEGW_CROSS_TRIPLET}")
  message(FATAL_ERROR "${OEGW_SYSROOT} is no ${OEGW_CROSS_DEBARCH} sysroot: make it with "
                      "scripts/cross-sysroot.sh ${OEGW_CROSS_DEBARCH} (or scripts/cross-build.sh ${OEGW_CROSS_DEBARCH})")
endif()
# try_compile projects (compiler checks, find_package(Threads)) read this file again: pass it on.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES OEGW_SYSROOT)

set(CMAKE_C_COMPILER ${OEGW_CROSS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${OEGW_CROSS_TRIPLET}-g++)
set(CMAKE_SYSROOT "${OEGW_SYSROOT}")
set(CMAKE_LIBRARY_ARCHITECTURE ${OEGW_CROSS_TRIPLET})

# Libraries, headers and CMake packages only from the sysroot; programs (idlc, lcm-gen,
# lcm-logger, python3, sh) only from this machine: the code generators run natively, CycloneDDS's
# idlc_generate() looks for idlc with NO_CMAKE_FIND_ROOT_PATH when cross-compiling.
set(CMAKE_FIND_ROOT_PATH "${OEGW_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# pkg-config (lcm, libsystemd, libsocketcan): the sysroot's .pc files only, their -I/-L paths
# prefixed with the sysroot.
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${OEGW_SYSROOT}")
set(ENV{PKG_CONFIG_LIBDIR}
    "${OEGW_SYSROOT}/usr/lib/${OEGW_CROSS_TRIPLET}/pkgconfig:${OEGW_SYSROOT}/usr/lib/pkgconfig:${OEGW_SYSROOT}/usr/share/pkgconfig")
unset(ENV{PKG_CONFIG_PATH})

# ctest and gtest_discover_tests run the target's test programs under qemu-user, the target's
# dynamic loader and libraries taken from the sysroot (-L). Programs that a test starts itself
# (sh -c "oegw ...", the example subscribers) go through binfmt_misc instead and find the sysroot
# through QEMU_LD_PREFIX, which scripts/cross-build.sh sets.
find_program(OEGW_CROSS_QEMU_PROGRAM ${OEGW_CROSS_QEMU} REQUIRED)
set(CMAKE_CROSSCOMPILING_EMULATOR ${OEGW_CROSS_QEMU_PROGRAM} -L ${OEGW_SYSROOT})

# The Debian package's Architecture (cmake/OegwPackage.cmake); CPack would ask this machine's dpkg.
set(OEGW_DEB_ARCH ${OEGW_CROSS_DEBARCH})
