# The Debian package (CPack's DEB generator), built by scripts/package.sh: the files of
# cmake/OegwInstall.cmake below the prefix /usr, /etc/oegw/oegw.yaml as a conffile, and the
# Depends dpkg-shlibdeps (dpkg-dev) computes from the Debian library packages the installed
# programs link. Installed binaries are stripped: the package carries no debug information.
# /usr/share/doc/oegw/copyright (Debian Policy §12.5, machine-readable DEP-5) is
# packaging/debian/copyright, installed by cmake/OegwInstall.cmake with the other docs.
# The team address, also the Upstream-Contact of packaging/debian/copyright (the deploy test
# checks that the two agree). A plain variable, not a cache entry: a cached value outlives a
# change here (a build tree configured earlier kept the old placeholder address).
set(OEGW_PACKAGE_MAINTAINER "oegw developers <oegw@localhost>")

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME oegw)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "${OEGW_PACKAGE_MAINTAINER}")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "CiA 852 operator-environment CANopen gateway")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # oegw_<version>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${OEGW_PACKAGE_MAINTAINER}")
set(CPACK_DEBIAN_PACKAGE_SECTION electronics)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# can-utils reads the recordings (log2asc, canplayer); libjs-chart.js draws `oegw replay --plot`.
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "can-utils, libjs-chart.js")
set(CPACK_DEBIAN_COMPRESSION_TYPE xz)
# Debian's control Description: CPack puts the summary line first and indents this long text.
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION "oegw runs on an operator cab's controller between two CAN buses. Towards the
host it is one CiA 852 / CiA 401 CANopen device (joysticks, pedals, encoders,
wheels, buttons, indicators, displays); towards the cab it is the CANopen
master of the cab's devices (elobau MFG grips, MCB-402 joystick controllers,
Novotechnik CiA 406 encoders, generic CiA 401 nodes). A mapping file
(/etc/oegw/oegw.yaml) says which device signal feeds which functional element;
every operator input is also published to DDS and LCM.

The package installs the daemon (oegw run, systemd unit oegw.service, not
enabled), the bench simulator oegw-sim, sample mapping and EDS files and the
example subscribers.")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${PROJECT_SOURCE_DIR}/packaging/debian/conffiles ${PROJECT_SOURCE_DIR}/packaging/debian/postinst
    ${PROJECT_SOURCE_DIR}/packaging/debian/prerm ${PROJECT_SOURCE_DIR}/packaging/debian/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)

# A cross-build (cmake/toolchains/debian-cross.cmake): the package is the target's, and its
# Depends come from the target's libraries in the sysroot. dpkg-shlibdeps finds them in the
# sysroot's library folders (-l), runs <triplet>-objdump for DEB_HOST_ARCH, and asks which package
# ships each one of the sysroot's index that scripts/cross-sysroot.sh writes (DPKG_ADMINDIR: the
# packages, their file lists under the sysroot's path, their symbols and shlibs files). cpack
# reads the environment from cmake/OegwCpackCross.cmake when it runs.
if(CMAKE_CROSSCOMPILING AND OEGW_DEB_ARCH)
  set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${OEGW_DEB_ARCH})
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS_PRIVATE_DIRS ${OEGW_SYSROOT}/lib/${CMAKE_LIBRARY_ARCHITECTURE}
                                                  ${OEGW_SYSROOT}/usr/lib/${CMAKE_LIBRARY_ARCHITECTURE})
  set(CPACK_OEGW_SHLIBS_ADMINDIR ${OEGW_SYSROOT}/var/lib/oegw-shlibs)
  set(CPACK_PROJECT_CONFIG_FILE ${PROJECT_SOURCE_DIR}/cmake/OegwCpackCross.cmake)
endif()
include(CPack)
