# Two commands: `make demo` (the main job) and `make test`. Both bootstrap .venv first.
VENV := .venv
STAMP := $(VENV)/.bootstrapped
BIN := $(VENV)/bin
DEMO := out/demo

.PHONY: demo test bench clean

$(STAMP): pyproject.toml scripts/bootstrap.sh
	scripts/bootstrap.sh
	touch $(STAMP)

# Two pytest workers, one test file each at a time (pytest-xdist): most tests wait on a browser, a Dask cluster,
# a subprocess or a compiler, so two workers on two cores take about 10 minutes instead of 14.5. No test's assertion
# depends on measured times (a compare page's verdicts are checked against every wording the protocol may give).
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

# Main job, the whole story at a small size: a dof signal of the depth-of-field scene, its
# pictures and sparsity analysis, then the equal-time comparison of path tracing with the
# CoSaMP reconstruction (thesis 8.1), the thesis's procedure beside ours, against a cached reference,
# then a two-scene suite of the methods that win.
demo: $(STAMP)
	$(BIN)/sparselt sample --scene dof-sculptures --kind dof --shape 128,128,16,16 --spp 16 --seed 1 --out $(DEMO)/signal --overwrite
	$(BIN)/sparselt show $(DEMO)/signal --out $(DEMO)/pictures --overwrite
	$(BIN)/sparselt analyze $(DEMO)/signal --gamma 1,0.25 --out $(DEMO)/analysis --overwrite
	# 64x64 pixels (a quarter of the signal's image plane), 3 seeds and 2 timing repeats per cell, so that the
	# verdicts carry intervals and the demo fits in 3 minutes; PT's ladder is automatic (up to 512 spp here: a speed-up beyond it is a bound).
	$(BIN)/sparselt compare --scene dof-sculptures --kind dof --shape 64,64,16,16 --methods pt,samples-mean,cosamp,cosamp-thesis,bilateral,cosamp-bilateral,oidn --spp 16,40 --seeds 1,2,3 --timing-repeats 2 --pt-ladder-max-spp 512 --reference-spp 1024 --out $(DEMO)/compare --overwrite
	# Then the suite: two scenes of the standard suite at 128x128 with the methods that win somewhere, aggregated
	# across scenes with bootstrap intervals, and an interactive viewer per scene (examples/demo-suite.toml).
	$(BIN)/sparselt suite examples/demo-suite.toml --out $(DEMO)/suite --overwrite --no-progress
	@echo "demo: pictures in $(DEMO)/pictures, sparsity analysis in $(DEMO)/analysis, comparison in $(DEMO)/compare (equal_time.md, summary.csv, table_8.md, quality_vs_time.png, image_grid.png, error_maps.png)"
	@echo "demo: report pages: file://$(CURDIR)/$(DEMO)/compare/index.html and file://$(CURDIR)/$(DEMO)/suite/index.html"

bench: $(STAMP)
	$(BIN)/python benchmarks/sampling_throughput.py
	$(BIN)/python benchmarks/fft_backends.py
	$(BIN)/python benchmarks/cosamp.py
	$(BIN)/python benchmarks/sft.py
	$(BIN)/python benchmarks/compare_overhead.py
	$(BIN)/python benchmarks/filters.py
	$(BIN)/python benchmarks/axis_aligned_overhead.py
	$(BIN)/python benchmarks/gradient_domain.py
	$(BIN)/python benchmarks/guided_throughput.py
	$(BIN)/python benchmarks/distributed_sampling.py
	$(BIN)/python benchmarks/sft_oracle.py
	$(BIN)/sparselt bench integrate --out out/bench-integrate --overwrite

clean:
	rm -rf $(VENV) out
