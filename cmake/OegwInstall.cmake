# What `cmake --install` and the Debian package (cmake/OegwPackage.cmake) put where: FHS places
# below the install prefix (docs/guides/install.md#installing).
#
#   bin/oegw, bin/oegw-sim                 the daemon and the bench simulator
#   lib/oegw/examples/                      the example programs of examples/ (not on PATH: their
#                                           generic names, dds_subscriber..., are not commands of
#                                           the product; docs/guides/install.md#installing says why)
#   lib/systemd/system/oegw.service         config/oegw.service, its program paths for this prefix
#   share/oegw/eds/*.eds                    the sample EDS files (subdevices/eds)
#   share/oegw/examples/*.yaml              the sample mapping files, EDS paths made absolute
#   share/doc/oegw/                         README.md, docs/**.md (the documentation's Markdown: its
#                                           links are relative, so they work there too),
#                                           mapping/README.md and subdevices/README.md (the
#                                           programs' messages name them; they point into docs/),
#                                           copyright (packaging/debian/copyright, DEP-5)
#   <sysconfdir>/oegw/oegw.yaml             config/cab.yaml as the default configuration (/etc for
#                                           the prefix /usr); an existing one is kept
#   <localstatedir>/lib/oegw/               the upstream store's folder (/var/lib/oegw)
#
# The unit and the mapping files name absolute paths, so they are written at install time, for the
# prefix of that install: CPack installs with the prefix /usr whatever the build tree was
# configured with, and `cmake --install --prefix` may change it too.
include(GNUInstallDirs)

install(TARGETS oegw oegw-sim RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

# Every executable examples/CMakeLists.txt defines, by target: a new example is installed as it is added.
get_property(_oegw_example_targets DIRECTORY ${PROJECT_SOURCE_DIR}/examples PROPERTY BUILDSYSTEM_TARGETS)
set(OEGW_EXAMPLE_PROGRAMS "")
foreach(_t ${_oegw_example_targets})
  get_target_property(_type ${_t} TYPE)
  if(_type STREQUAL "EXECUTABLE")
    list(APPEND OEGW_EXAMPLE_PROGRAMS ${_t})
  endif()
endforeach()
install(TARGETS ${OEGW_EXAMPLE_PROGRAMS} RUNTIME DESTINATION lib/oegw/examples)
# Only what is installed, for scripts/package.sh: `cmake --build B --target oegw_installed`.
add_custom_target(oegw_installed)
add_dependencies(oegw_installed oegw oegw-sim ${OEGW_EXAMPLE_PROGRAMS})

file(GLOB OEGW_SAMPLE_EDS CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/subdevices/eds/*.eds)
install(FILES ${OEGW_SAMPLE_EDS} DESTINATION ${CMAKE_INSTALL_DATADIR}/oegw/eds)

install(FILES README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
# Debian Policy §12.5: every package's copyright file at /usr/share/doc/<package>/copyright.
install(FILES packaging/debian/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/docs FILES_MATCHING PATTERN "*.md")
install(FILES mapping/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR}/mapping)
install(FILES subdevices/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR}/subdevices)

# The generated files: cmake/install_generated.cmake runs inside the install step and reads the
# sources then, so an edited unit or sample needs no reconfigure.
set(OEGW_SAMPLE_MAPPINGS ${PROJECT_SOURCE_DIR}/config/cab.yaml ${PROJECT_SOURCE_DIR}/config/demo.yaml)
install(CODE "
  set(OEGW_UNIT \"${PROJECT_SOURCE_DIR}/config/oegw.service\")
  set(OEGW_SAMPLE_MAPPINGS \"${OEGW_SAMPLE_MAPPINGS}\")
  set(OEGW_DEFAULT_MAPPING \"${PROJECT_SOURCE_DIR}/config/cab.yaml\")
  set(OEGW_STAGING \"${PROJECT_BINARY_DIR}/install-generated\")
  set(OEGW_BINDIR \"${CMAKE_INSTALL_BINDIR}\")
  set(OEGW_DATADIR \"${CMAKE_INSTALL_DATADIR}\")
  set(OEGW_SYSCONFDIR \"${CMAKE_INSTALL_SYSCONFDIR}\")
  set(OEGW_LOCALSTATEDIR \"${CMAKE_INSTALL_LOCALSTATEDIR}\")
  include(\"${PROJECT_SOURCE_DIR}/cmake/install_generated.cmake\")
")
