"""Command-line tools that compose sim and autopilot, by role: the product's tools at the top level (ground station,
run commands, the SITL test API, encounter generator, monitor, figures) and ``campaign``; the paper's research code
(``research``) and the benchmarks (``benchmarks``), which the wheel leaves out."""
