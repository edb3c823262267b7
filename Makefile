# Two commands: `make demo` and `make test`. Both set up .venv from pyproject.toml.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
# Numba compiles once per machine; keep its cache inside the checkout. voxfield keys a folder
# inside it on its source (Numba checks only a cached function's own file, not the code it
# inlines from other files), so an edit recompiles.
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache

.PHONY: demo test fuzz lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

# The demo's pictures render side by side, one per core: on a first run each compiles its
# own kernels, which takes most of the time, and one compilation uses one core.
DEMO_RENDER := $(BIN)/voxfield render builtin:pillars --camera orbit --size 384
DEMO_JOBS   := $(shell nproc 2>/dev/null || echo 2)
# The longest compilations first, so that make starts them first.
DEMO_IMAGES := demo-error-aware demo-light-field demo-reference demo-lod2 demo-cone \
               demo-error-mask
# Each command's lines kept together where make can (GNU make 4; macOS's 3.81 interleaves).
DEMO_SYNC   := $(if $(filter output-sync,$(.FEATURES)),--output-sync=target)
.PHONY: $(DEMO_IMAGES)

demo: $(STAMP)
	$(BIN)/voxfield info builtin:pillars
	@echo "rendering $(words $(DEMO_IMAGES)) pictures ($(DEMO_JOBS) at a time; a first run compiles the kernels: a minute or two)"
	@$(MAKE) --no-print-directory -j$(DEMO_JOBS) $(DEMO_SYNC) $(DEMO_IMAGES)
	$(DEMO_RENDER) --renderer reference --out out/pillars_reference.exr
	@echo "demo images written to out/"

# The EA thesis: one ray a pixel at a coarse LOD, refined 2×2 one LOD finer where the
# precomputed error says the coarse node would show; its ray-count and LOD maps beside it.
demo-error-aware: $(STAMP)
	$(DEMO_RENDER) --renderer error-aware --counters --out out/pillars_error_aware.png
# The probe thesis: a 3x3x3 grid of light probes baked from the octree, then a view among
# them answered from the probes alone, beside the octree's render of the same view.
demo-light-field: $(STAMP)
	$(BIN)/voxfield bake builtin:pillars --grid 3x3x3 --resolution 256 --renderer lod \
		--relocate --fresh --quiet --out out/pillars_probes
	$(BIN)/voxfield probe-render out/pillars_probes --scene builtin:pillars --camera room \
		--size 384 --compare --counters --out out/pillars_light_field.png
demo-reference: $(STAMP)
	$(DEMO_RENDER) --renderer reference --counters --out out/pillars_reference.png
demo-lod2: $(STAMP)
	$(DEMO_RENDER) --renderer lod --lod 2 --out out/pillars_lod2.png
# Each pixel at the LOD of its cone; on this small scene a pixel's cone is narrower than a
# voxel everywhere, so nodes up to 8 footprints wide are accepted to let the far side coarsen.
demo-cone: $(STAMP)
	$(DEMO_RENDER) --renderer lod --lod cone --cone-scale 8 --counters --out out/pillars_cone.png
demo-error-mask: $(STAMP)
	$(BIN)/voxfield errors show 0b00110011 --threshold 0.3 --out out/error_mask_51.png

# The CUDA kernels run under Numba's simulator (no GPU needed; JIT off so the shared @njit
# code runs as Python inside simulated threads), then the suite proper in TEST_WORKERS
# processes (pytest-xdist), a test file per process at a time so that its tests share the
# kernels it compiles; the compiled kernels go to the one cache folder both processes read.
TEST_WORKERS ?= 2
test: $(STAMP)
	NUMBA_ENABLE_CUDASIM=1 NUMBA_DISABLE_JIT=1 timeout 60 $(BIN)/python -m pytest -q -m cuda \
		-p no:cacheprovider tests/cuda
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile

# Long fuzzing run (tests/fuzz with many more examples); `make test` runs a short seeded one.
fuzz: $(STAMP)
	HYPOTHESIS_PROFILE=long $(BIN)/python -m pytest -q tests/fuzz

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_traversal.py

clean:
	rm -rf $(VENV) out .numba_cache
