# Read by cpack (CPACK_PROJECT_CONFIG_FILE, cmake/OegwPackage.cmake) in a cross-build: the
# environment dpkg-shlibdeps needs to compute the target package's Depends from the sysroot.
if(NOT IS_DIRECTORY "${CPACK_OEGW_SHLIBS_ADMINDIR}")
  message(FATAL_ERROR "${CPACK_OEGW_SHLIBS_ADMINDIR}: no index of the sysroot's packages (scripts/cross-sysroot.sh "
                      "${CPACK_DEBIAN_PACKAGE_ARCHITECTURE} writes it)")
endif()
set(ENV{DPKG_ADMINDIR} "${CPACK_OEGW_SHLIBS_ADMINDIR}")
set(ENV{DEB_HOST_ARCH} "${CPACK_DEBIAN_PACKAGE_ARCHITECTURE}")
