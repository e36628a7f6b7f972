# longstep: `make run` runs the default demo, `make test` is what CI runs.
CARGO ?= cargo
BIN := target/release/longstep

.PHONY: run test test-all bench figures cmake fmt

# chemfiles' C++ core is built with CMake; install it when missing (pip first, apt second).
cmake:
	@command -v cmake >/dev/null 2>&1 || python3 -m pip install --quiet cmake || true
	@command -v cmake >/dev/null 2>&1 || (apt-get update -qq && apt-get install -y -qq cmake)
	@command -v cmake >/dev/null 2>&1 || { echo "CMake is missing and could not be installed" >&2; exit 1; }

run: cmake
	$(CARGO) build --release
	$(BIN) run systems/three-spring.toml

test: cmake
	$(CARGO) fmt --check
	$(CARGO) clippy --release --all-targets -- -D warnings
	$(CARGO) test --release

test-all: test
	$(CARGO) test --release -- --ignored

bench: cmake
	$(CARGO) bench

fmt:
	$(CARGO) fmt

# docs/pseudo-energy.md and docs/data/pseudo-energy/*.csv (MEMM18 studies, several minutes).
figures: figures-pseudo-energy

.PHONY: figures-pseudo-energy

figures-pseudo-energy: cmake
	$(CARGO) bench --bench pseudo_energy
	$(CARGO) run --release --example pseudo_energy_report
