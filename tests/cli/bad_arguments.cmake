# Bad arguments give a non-zero exit and a message that names the problem.
include(${CMAKE_CURRENT_LIST_DIR}/lib/expect.cmake)
expect_failure("order" tables --order 9)
expect_failure("order" tables --order 1)
expect_failure("order" tables --order nan)
expect_failure("resolution" tables --resolution 1)
expect_failure("param" tables --param gamma)
expect_failure("no-such" tables --no-such-flag)
expect_failure("subcommand|required" )
# A repeated --param is an error naming both values, before anything renders.
expect_failure("--param 'order' given twice \\('order=3' and 'order=5'\\)" render --scene spheres --technique shexp --param order=3 --param order=5 --out ${WORK_DIR}/twice)
expect_failure("--param 'order' given twice" experiment shexp_orders --quick --param order=3 --param order=4 --out ${WORK_DIR}/twice)
# render's camera options: three finite numbers per vector, a field of view inside (0, 179).
expect_failure("--camera-position '1,2'" render --scene spheres --technique shexp --camera-position 1,2 --out ${WORK_DIR}/cam)
expect_failure("--camera-target 'a,b,c'" render --scene spheres --technique shexp --camera-target a,b,c --out ${WORK_DIR}/cam)
expect_failure("--camera-up '0,nan,0'" render --scene spheres --technique shexp --camera-up 0,nan,0 --out ${WORK_DIR}/cam)
expect_failure("--fov" render --scene spheres --technique shexp --fov 200 --out ${WORK_DIR}/cam)
expect_failure("position equal to target|position.*target" render --scene spheres --technique shexp --camera-position 0,0.3,0 --out ${WORK_DIR}/cam)
