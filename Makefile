# Two commands: `make demo` (the main job) and `make test`. Both bootstrap .venv first.
VENV := .venv
STAMP := $(VENV)/.bootstrapped
BIN := $(VENV)/bin
DEMO := out/demo

.PHONY: demo test bench clean

$(STAMP): pyproject.toml scripts/bootstrap.sh
	scripts/bootstrap.sh
	touch $(STAMP)

test: $(STAMP)
	$(BIN)/python -m pytest -q

# Main job: a dof signal of the depth-of-field scene, its integrated image and slices,
# and the path-traced reference at the same resolution.
demo: $(STAMP)
	$(BIN)/sparselt sample --scene dof-sculptures --kind dof --shape 128,128,16,16 --spp 16 --seed 1 --out $(DEMO)/signal --overwrite
	$(BIN)/sparselt show $(DEMO)/signal --out $(DEMO)/pictures
	$(BIN)/sparselt analyze $(DEMO)/signal --out $(DEMO)/analysis --overwrite
	$(BIN)/sparselt render --scene dof-sculptures --resolution 128,128 --spp 2048 --out $(DEMO)/reference --overwrite
	@echo "demo: pictures in $(DEMO)/pictures, sparsity analysis in $(DEMO)/analysis, reference in $(DEMO)/reference"

bench: $(STAMP)
	$(BIN)/python benchmarks/sampling_throughput.py
	$(BIN)/python benchmarks/fft_backends.py
	$(BIN)/python benchmarks/cosamp.py
	$(BIN)/python benchmarks/sft.py
	$(BIN)/sparselt bench integrate --out out/bench-integrate --overwrite

clean:
	rm -rf $(VENV) out
