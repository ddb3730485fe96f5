# Bad arguments give a non-zero exit and a message that names the problem.
include(${CMAKE_CURRENT_LIST_DIR}/lib/expect.cmake)
expect_failure("order" tables --order 9)
expect_failure("order" tables --order 1)
expect_failure("order" tables --order nan)
expect_failure("resolution" tables --resolution 1)
expect_failure("param" tables --param gamma)
expect_failure("no-such" tables --no-such-flag)
expect_failure("subcommand|required" )
