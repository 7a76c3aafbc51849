# Runs inside the install step (cmake --install, CPack): writes the files that name absolute paths
# for the prefix of this install, CMAKE_INSTALL_PREFIX here (CPack: /usr), and installs them.
# Set by cmake/OegwInstall.cmake: OEGW_UNIT, OEGW_SAMPLE_MAPPINGS, OEGW_DEFAULT_MAPPING,
# OEGW_STAGING and the GNUInstallDirs folders OEGW_BINDIR, OEGW_DATADIR, OEGW_SYSCONFDIR,
# OEGW_LOCALSTATEDIR as configured (relative, or absolute if so given).

# A folder as GNUInstallDirs makes it absolute (its CMAKE_INSTALL_FULL_<dir>), for the prefix of
# this install rather than the one configured: etc and var of the prefixes / and /usr are /etc
# and /var, of /opt/<x> /etc/opt/<x> and /var/opt/<x>.
function(oegw_full_dir out dir)
  set(p "${CMAKE_INSTALL_PREFIX}")
  string(REGEX REPLACE "/+$" "" p "${p}")
  if(IS_ABSOLUTE "${dir}")
    set(full "${dir}")
  elseif(dir MATCHES "^(etc|var)$" AND (p STREQUAL "" OR p STREQUAL "/usr"))
    set(full "/${dir}")
  elseif(dir MATCHES "^(etc|var)$" AND p MATCHES "^/opt/(.+)$")
    set(full "/${dir}/opt/${CMAKE_MATCH_1}")
  else()
    set(full "${p}/${dir}")
  endif()
  set(${out} "${full}" PARENT_SCOPE)
endfunction()

oegw_full_dir(bindir "${OEGW_BINDIR}")
oegw_full_dir(datadir "${OEGW_DATADIR}")
oegw_full_dir(sysconfdir "${OEGW_SYSCONFDIR}")
oegw_full_dir(localstatedir "${OEGW_LOCALSTATEDIR}")
set(eds_dir "${datadir}/oegw/eds")
file(MAKE_DIRECTORY "${OEGW_STAGING}")

# The unit: its program paths (written for /usr/bin, or /usr/local/bin) name this install's bindir;
# nothing else of its text changes.
file(READ "${OEGW_UNIT}" unit)
string(REGEX REPLACE "/usr(/local)?/bin/oegw" "${bindir}/oegw" unit "${unit}")
file(WRITE "${OEGW_STAGING}/oegw.service" "${unit}")
file(INSTALL DESTINATION "${CMAKE_INSTALL_PREFIX}/lib/systemd/system" TYPE FILE FILES "${OEGW_STAGING}/oegw.service")

# The sample mapping files: every `eds:` path names the installed EDS file of the same name, so
# that `oegw check` works on them from any folder.
foreach(src ${OEGW_SAMPLE_MAPPINGS})
  get_filename_component(name "${src}" NAME)
  file(READ "${src}" text)
  string(REGEX REPLACE "(eds: *)([^ ,}\n]*/)?([^/ ,}\n]+\\.eds)" "\\1${eds_dir}/\\3" text "${text}")
  file(WRITE "${OEGW_STAGING}/${name}" "${text}")
  file(INSTALL DESTINATION "${datadir}/oegw/examples" TYPE FILE FILES "${OEGW_STAGING}/${name}")
endforeach()

# The default configuration: config/cab.yaml as written for this install. An existing one is the
# integrator's and is kept (the package's conffile handling does the same for upgrades).
get_filename_component(default_name "${OEGW_DEFAULT_MAPPING}" NAME)
set(conf "${sysconfdir}/oegw/oegw.yaml")
if(EXISTS "$ENV{DESTDIR}${conf}")
  message(STATUS "Keeping: $ENV{DESTDIR}${conf} (the shipped default: ${datadir}/oegw/examples/${default_name})")
else()
  file(INSTALL DESTINATION "${sysconfdir}/oegw" TYPE FILE RENAME oegw.yaml FILES "${OEGW_STAGING}/${default_name}")
endif()

# The upstream store's folder (upstream.store: /var/lib/oegw/upstream.store), also made by the
# unit's StateDirectory=oegw; here so that `oegw run` by hand finds it.
file(MAKE_DIRECTORY "${OEGW_STAGING}/state/oegw")
file(INSTALL DESTINATION "${localstatedir}/lib" TYPE DIRECTORY FILES "${OEGW_STAGING}/state/oegw")
