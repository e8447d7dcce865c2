"""Jobs: run, compare, manoeuvres, sweeps and the benchmark: build -> loop -> outputs."""
