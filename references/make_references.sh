#!/usr/bin/env bash
# Re-creates the high-spp reference renders of the bundled scenes with brdflab itself.
# Seeds differ from the test seeds (tests use small seeds) so references are independent of test renders.
set -euo pipefail
cd "$(dirname "$0")/.."
brdflab render scenes/cbox/cbox_diffuse.xml       --spp 1024 --seed 90001 -o references/cbox_diffuse.exr --quiet
brdflab render scenes/cbox/cbox_spheres_mis.xml   --spp 1024 --seed 90002 -o references/cbox_spheres.exr --quiet
brdflab render scenes/cbox/cbox_substrate_mis.xml --spp 1024 --seed 90003 -o references/cbox_substrate.exr --quiet
brdflab render scenes/veach/veach_mis.xml         --spp 2048 --seed 90004 -o references/veach_mis.exr --quiet
brdflab render scenes/envlit/envlit_mis.xml       --spp 2048 --seed 90005 -o references/envlit.exr --quiet
brdflab render scenes/checker/checker_point.xml   --spp 1024 --seed 90006 -o references/checker_point.exr --quiet
brdflab render scenes/lights/sphere_light_mis.xml   --spp 4096 --seed 90007 -o references/sphere_light.exr --quiet
brdflab render scenes/lights/polygon_lights_mis.xml --spp 4096 --seed 90008 -o references/polygon_lights.exr --quiet
brdflab render scenes/lights/mixed_lights_mis.xml   --spp 4096 --seed 90009 -o references/mixed_lights.exr --quiet
