# Fails when README.md's configuration reference differs from `certislam config dump --markdown`
# (the table between the config-reference markers is generated; see README.md).
# Usage: cmake -DBINARY=... -DREADME=... -P readme_config_table.cmake
execute_process(COMMAND ${BINARY} config dump --markdown OUTPUT_VARIABLE generated
                RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "${BINARY} config dump --markdown failed (${status})")
endif()
file(READ ${README} readme)
string(REGEX MATCH "<!-- config-reference:begin -->\n(.*)<!-- config-reference:end -->" _ "${readme}")
if(NOT CMAKE_MATCH_1 STREQUAL generated)
  message(FATAL_ERROR "README.md's configuration table is out of date: replace the lines between "
                      "<!-- config-reference:begin --> and <!-- config-reference:end --> with the "
                      "output of `certislam config dump --markdown`")
endif()
