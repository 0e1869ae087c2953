"""The casting kernels both methods share (rays, traversal, cubic, accumulation, shading, shadows),
and beside them the truth the tests and studies measure them against: exact and high-precision
references (`reference`, `mpcubic`, `ideal`), hard cases (`hardcases`, `hardfields`, `hardrays`),
other root finders (`roots_alt`) and the bricked layout (`bricks`), none of which a render uses."""
