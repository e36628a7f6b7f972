# longstep: `make run` runs the default demo, `make test` is what CI runs.
CARGO ?= cargo
BIN := target/release/longstep

.PHONY: run test test-all test-slurm bench figures figures-studies cmake fmt

# chemfiles' C++ core is built with CMake; install it when missing (pip first, apt second).
cmake:
	@command -v cmake >/dev/null 2>&1 || python3 -m pip install --quiet cmake || true
	@command -v cmake >/dev/null 2>&1 || (apt-get update -qq && apt-get install -y -qq cmake)
	@command -v cmake >/dev/null 2>&1 || { echo "CMake is missing and could not be installed" >&2; exit 1; }

# The main job in one go: how long a step each method can take (a step-size safety scan of
# GSS98's three-spring system), with its table and chart.
DEMO := out/demo
run: cmake
	$(CARGO) build --release
	$(BIN) scan steps systems/three-spring.toml --methods impulse,short-average,long-average \
		--h 0.1:0.7:0.01 --inner 40 --t-end 250 --repeats 0 --quiet --out $(DEMO)
	@echo
	@echo "Table: $(DEMO)/scan.csv   chart: $(DEMO)/scan.png (open it: impulse's drift peaks at the"
	@echo "resonant steps marked on it; the mollified methods stay lower). The same on a water box"
	@echo "or a topology:"
	@echo "  $(BIN) scan steps systems/water-box/scene.toml --methods impulse --h 1fs:4fs:0.5fs --dt 0.5fs --t-end 2ps"
	@echo "  $(BIN) scan steps systems/alanine-dipeptide-amber/ala2-solvated-pme.toml --study studies/ala2-production-nve.toml --t-end 2ps"

test: cmake
	$(CARGO) fmt --check
	$(CARGO) clippy --release --all-targets -- -D warnings
	$(CARGO) test --release

test-all: test
	$(CARGO) test --release -- --ignored

# The Slurm job array of docs/studies.md on a single-node Slurm started here (root; installs
# slurm-wlm and munge when missing): merged shards equal the unsharded scan byte for byte.
test-slurm: cmake
	$(CARGO) build --release
	scripts/test_slurm.sh $(BIN)

bench: cmake
	$(CARGO) bench

# Pictures for docs/ (not committed: regenerate with `make figures`). CSVs go to out/figures.
FIGURES := docs/figures
FIGURE_DATA := out/figures
MAP := $(BIN) stability-map --quiet --h 0.5
GROWTH := $(BIN) scan growth systems/three-spring.toml --quiet --inner 200
PROP1 := --set 'omega1=pi-1/pi^3' --set 'omega2=3*pi-1/(27*pi^3)'
STIFFNESS := $(BIN) scan stiffness systems/two-spring.toml --quiet --param omega1 --range 0:32 --n 400
figures: cmake
	$(CARGO) build --release
	mkdir -p $(FIGURES) $(FIGURE_DATA)
# docs/production.md: ns/day against the outer step, from the committed sitting and study.
	python3 scripts/production_chart.py --date 2026-11-26 --sitting 2026-11-26-b --out $(FIGURES)
# GSS98 Figure 1 (and 4): LongAverage, h = 1/2, the strip near Γ1 + Γ2 = 2π.
	$(MAP) --method long-average --gamma1 0:2*pi --gamma2 0:2*pi --n 1000 \
		--out $(FIGURE_DATA)/fig1-long-average.csv --png $(FIGURES)/fig1-long-average.png
# Figure 2: the wide end near Γ2 = 0.
	$(MAP) --method long-average --gamma1 5.6:6.0 --gamma2 0:0.4 --n 800 \
		--out $(FIGURE_DATA)/fig2-wide-end.csv --png $(FIGURES)/fig2-wide-end.png
# Figure 3: the narrow end near (π, π), at u = π − Γ2 ≈ 0.006 (width ≈ 3e-7).
	$(MAP) --method long-average --gamma1 3.1475920:3.1475930 --gamma2 3.1355925:3.1355935 \
		--n 400 --out $(FIGURE_DATA)/fig3-narrow-end.csv --png $(FIGURES)/fig3-narrow-end.png
# Figure 5: ShortAverage, type-2 bands near Γi = π.
	$(MAP) --method short-average --gamma1 0:2*pi --gamma2 0:2*pi --n 1000 \
		--out $(FIGURE_DATA)/fig5-short-average.csv --png $(FIGURES)/fig5-short-average.png
# The census: instability types over [0, 4π]² for the four methods.
	for m in impulse short-average long-average linear-average; do \
		$(MAP) --method $$m --gamma1 0:4*pi --gamma2 0:4*pi --n 1000 --colour type \
			--out $(FIGURE_DATA)/types-$$m.csv --png $(FIGURES)/types-$$m.png || exit 1; \
	done
# Integrator mode: velocity Verlet (single step) on the three-spring scene.
	$(MAP) --mode integrator --method verlet --gamma1 0:2*pi --gamma2 0:2*pi --n 200 \
		--out $(FIGURE_DATA)/verlet-integrator.csv --png $(FIGURES)/verlet-integrator.png
# Integrator mode with coarse inner steps: what the inner Verlet adds (docs/stability.md).
	for m in impulse short-average long-average linear-average; do for k in 5 10 20; do \
		$(MAP) --mode integrator --inner $$k --method $$m --gamma1 0:2*pi --gamma2 0:2*pi --n 400 \
			--colour type --out $(FIGURE_DATA)/coarse-k$$k-$$m.csv \
			--png $(FIGURES)/coarse-k$$k-$$m.png || exit 1; \
	done; done
# GSS98 Figures 6-10: long runs at h = 1/2, K = 200 inner steps, GSS98's parameter sets.
	$(GROWTH) --method long-average --h 0.5,0.49 --t-end 2000 $(PROP1) \
		--out $(FIGURE_DATA)/fig6 --png $(FIGURES)/fig6-long-average.png
	$(GROWTH) --method long-average,impulse,short-average,linear-average --h 0.5 --t-end 3000 \
		$(PROP1) --set p0=1e-8 --fit 1e10:1e14 \
		--out $(FIGURE_DATA)/fig6-linear --png $(FIGURES)/fig6-linear-regime.png
	$(GROWTH) --method long-average --h 0.5,0.49 --t-end 10000 $(PROP1) --set angle=pi/48 \
		--out $(FIGURE_DATA)/fig7 --png $(FIGURES)/fig7-angle-pi-48.png
	$(GROWTH) --method long-average --h 0.5,0.49 --t-end 10000 $(PROP1) --set angle=pi/12 \
		--out $(FIGURE_DATA)/fig8 --png $(FIGURES)/fig8-angle-pi-12.png
	$(GROWTH) --method long-average,short-average,impulse,linear-average --h 0.5 --t-end 3000 \
		--set 'omega1=2*pi-1/(2*pi^3)' --set omega2=0 \
		--out $(FIGURE_DATA)/fig9 --png $(FIGURES)/fig9-type-2.png
	$(GROWTH) --method long-average,linear-average,short-average,impulse --h 0.5 --t-end 3000 \
		--set 'omega1=4*pi-1/(16*pi)' --set omega2=0 \
		--out $(FIGURE_DATA)/fig10 --png $(FIGURES)/fig10-type-3-paper.png
	$(GROWTH) --method long-average,linear-average,short-average,impulse --h 0.5 --t-end 3000 \
		--set 'omega1=4*pi-1/(16*pi)' --set omega2=2 \
		--out $(FIGURE_DATA)/fig10-third-spring --png $(FIGURES)/fig10-type-3-third-spring.png
# GSS98 Figures 11-13: largest position error against Ω1 on the two-spring scene.
	$(STIFFNESS) --method impulse --h 0.5,0.25,0.125 --t-end 8 \
		--out $(FIGURE_DATA)/fig11.csv --png $(FIGURES)/fig11-impulse.png
	$(STIFFNESS) --method long-average --h 0.5,0.25 --t-end 16 \
		--out $(FIGURE_DATA)/fig12.csv --png $(FIGURES)/fig12-long-average.png
	$(STIFFNESS) --method long-average,short-average,impulse --h 0.5,0.25 --t-end 16 \
		--out $(FIGURE_DATA)/fig13.csv --png $(FIGURES)/fig13-three-methods.png
	$(MAKE) figures-studies

# docs/studies.md and docs/methods/*: work-precision charts per scene family, a step scan.
CHART := $(BIN) chart work-precision --quiet
ALL_METHODS := verlet,impulse,impulse-midpoint,short-average,long-average,linear-average,pseudo-energy,adaptive-verlet,structural-zd,structural-zds
figures-studies:
	$(CARGO) build --release
	mkdir -p $(FIGURES)/studies
	$(CHART) systems/two-spring.toml --methods $(ALL_METHODS) \
		--h-list 0.4,0.2,0.1,0.05,0.025 --inner 10 --block 2 --t-end 8 \
		--reference-method structural-zds --reference-h 0.003125 --out $(FIGURE_DATA)/wp-two-spring
	cp $(FIGURE_DATA)/wp-two-spring/error-vs-force-evaluations.png $(FIGURES)/studies/wp-two-spring.png
	$(CHART) systems/fpu.toml --methods $(ALL_METHODS) --quadrature gl3 \
		--h-list 0.04,0.02,0.01,0.005 --inner 20 --block 2 --t-end 4 \
		--reference-method structural-zds --reference-h 0.000625 --out $(FIGURE_DATA)/wp-fpu
	cp $(FIGURE_DATA)/wp-fpu/error-vs-force-evaluations.png $(FIGURES)/studies/wp-fpu.png
	$(CHART) systems/kepler.toml --set eccentricity=0.9 --methods verlet,adaptive-verlet,structural-zd,structural-zds \
		--h-list 0.04,0.02,0.01,0.005 --block 2 --t-end 2*pi --sample 0.04 \
		--reference-method structural-zds --reference-h 0.00125 --out $(FIGURE_DATA)/wp-kepler
	cp $(FIGURE_DATA)/wp-kepler/error-vs-force-evaluations.png $(FIGURES)/studies/wp-kepler.png
	$(CHART) systems/pendulum.toml --methods verlet,adaptive-verlet,structural-zd,structural-zds \
		--h-list 0.4,0.2,0.1,0.05 --block 2 --t-end 20 --sample 0.4 \
		--reference-method structural-zds --reference-h 0.0125 --out $(FIGURE_DATA)/wp-pendulum
	cp $(FIGURE_DATA)/wp-pendulum/error-vs-force-evaluations.png $(FIGURES)/studies/wp-pendulum.png
	$(CHART) systems/water-box/scene.toml --methods verlet,impulse,short-average,long-average,linear-average,pseudo-energy \
		--h-list 4fs,2fs,1fs,0.5fs --dt 0.25fs --t-end 200fs --out $(FIGURE_DATA)/wp-water
	cp $(FIGURE_DATA)/wp-water/error-vs-force-evaluations.png $(FIGURES)/studies/wp-water.png
	$(BIN) scan steps systems/molecules/butane.toml --methods verlet,impulse,short-average,linear-average,long-average \
		--h 0.5fs:8fs:0.25fs --dt 0.25fs --t-end 10ps --drift-bound 5e-7 --energy-every 4 --quiet \
		--out $(FIGURE_DATA)/scan-butane
	cp $(FIGURE_DATA)/scan-butane/scan.png $(FIGURES)/studies/scan-butane.png
	$(BIN) scan steps systems/three-spring.toml --methods impulse,short-average,linear-average,long-average \
		--h 0.15:0.7:0.005 --inner 40 --t-end 250 --blowup 0.2 --quiet --out $(FIGURE_DATA)/scan-three-spring
	cp $(FIGURE_DATA)/scan-three-spring/scan.png $(FIGURES)/studies/scan-three-spring.png

fmt:
	$(CARGO) fmt

# docs/pseudo-energy.md and docs/data/pseudo-energy/*.csv (MEMM18 studies, several minutes).
figures: figures-pseudo-energy

.PHONY: figures-pseudo-energy

figures-pseudo-energy: cmake
	$(CARGO) bench --bench pseudo_energy
	$(CARGO) run --release --example pseudo_energy_report
