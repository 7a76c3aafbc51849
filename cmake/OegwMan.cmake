# The manual pages oegw(1) and oegw.yaml(5) and the bash completion of oegw, generated at build
# time by scripts/make-man.sh from the built `oegw` (its --help and every sub-command's) and from
# docs/reference/mapping-file.md, so that neither can drift from the program or the documentation
# (docs/developer/docs-site.md#manual-pages). help2man and lowdown are Debian packages
# (scripts/install-deps.sh). A cross build runs its `oegw` under CMAKE_CROSSCOMPILING_EMULATOR.
find_program(OEGW_HELP2MAN help2man)
find_program(OEGW_LOWDOWN lowdown)
if(NOT OEGW_HELP2MAN OR NOT OEGW_LOWDOWN)
  message(FATAL_ERROR "help2man and lowdown make the manual pages: scripts/install-deps.sh installs them")
endif()
set(OEGW_MAN_DIR ${PROJECT_BINARY_DIR}/man)
set(OEGW_MAN_FILES ${OEGW_MAN_DIR}/oegw.1.gz ${OEGW_MAN_DIR}/oegw.yaml.5.gz ${OEGW_MAN_DIR}/oegw.bash)
add_custom_command(
  OUTPUT ${OEGW_MAN_FILES}
  COMMAND sh ${PROJECT_SOURCE_DIR}/scripts/make-man.sh ${OEGW_MAN_DIR} ${PROJECT_SOURCE_DIR}
          $<TARGET_FILE:oegw> ${CMAKE_CROSSCOMPILING_EMULATOR}
  DEPENDS oegw ${PROJECT_SOURCE_DIR}/scripts/make-man.sh ${PROJECT_SOURCE_DIR}/docs/reference/mapping-file.md
  COMMENT "oegw(1), oegw.yaml(5) and the bash completion (scripts/make-man.sh)"
  VERBATIM)
add_custom_target(oegw_man ALL DEPENDS ${OEGW_MAN_FILES})
add_dependencies(oegw_installed oegw_man)
install(FILES ${OEGW_MAN_DIR}/oegw.1.gz DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
install(FILES ${OEGW_MAN_DIR}/oegw.yaml.5.gz DESTINATION ${CMAKE_INSTALL_MANDIR}/man5)
install(FILES ${OEGW_MAN_DIR}/oegw.bash DESTINATION ${CMAKE_INSTALL_DATADIR}/bash-completion/completions
        RENAME oegw)
