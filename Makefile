# The project's commands. `make demo` and `make test` are the README's two commands;
# CI (.ci/run) runs `make lint` and `make test`.
CARGO ?= cargo

.PHONY: test-asan demo test lint test-python test-ray lint-python bench-python bench bench-c bench-net bench-peers bench-sim zenoh test-zenoh bench-zenoh ros2 test-ros2 bench-ros2 ros2-c ros2-python fuzz fuzz-long soak soak-recorder fmt docs

## Run the main demo: W-CMOMMT in the simulator (the paper's setting, a sweep, a robot killed
## halfway) for BLE and every baseline; prints a short summary (BLE against each baseline, whether
## the paper's claim held) and writes ayllu-report/ (index.html replays any run; tables.txt).
## Cargo's own progress shows while it builds (the first build takes a minute or two).
demo:
	@echo "make demo: building the ayllu tool (release; the first build takes a minute or two)..."
	$(CARGO) build --release -p ayllu-cli
	@echo "make demo: running the study (1680 simulated runs, about 15-40 s; progress on stderr)..."
	@$(TARGET_DIR)/release/ayllu sim cmommt

PYTHON ?= python3
# Where cargo puts binaries (honours CARGO_TARGET_DIR).
TARGET_DIR ?= $(or $(CARGO_TARGET_DIR),target)

## Run every test: Rust (unit, rule, property, golden vectors, examples, processes over real
## sockets, the report page in headless Chromium), AylluLite C and Python (golden vectors,
## node logic over loopback), libayllu's C tests under ASan+UBSan and its C++17 header check,
## and the core's pointer paths under ASan (test-asan).
## Installs Debian's chromium, pytest and ruff first if missing. Ends with a table of where the
## time went (each suite's build and run apart) and how many tests each ran (scripts/test-step).
STEP = scripts/test-step
# Every cargo build of `make test` after the first is this same command, so that nothing is
# compiled twice with different features (cargo's features for one package differ from the
# workspace's: see crates/ayllu-c/Makefile). It builds the tests, the tool (target/debug/ayllu,
# which the integration tests run) and the C library (target/debug/libayllu_c.a). Examples are
# left out (`--lib --bins --tests`): the tests compile and run each of them from its file
# (`#[path]`), and `make lint`'s clippy checks them all; scripts/workspace-test asks for the same.
WORKSPACE_TESTS = $(CARGO) test --workspace --exclude ayllu-ros2 --lib --bins --tests
# Four test threads, not one per core: the tool's tests wait on real clocks (a served world
# for 45 s, robots as processes), and while they wait the others run. Verdicts never depend on
# timing, so more threads only change how long it takes. For the same reason make test runs
# the test binaries themselves at once (scripts/workspace-test --all), where `cargo test` runs
# them one after another.
TEST_THREADS ?= 4
# The test build leaves the C library in target/debug/deps (cargo copies a library up to
# target/debug only when it is built for itself); `cp -p` puts it where the C Makefile and an
# install look, keeping its time so the C programs are relinked only when it changed.
C_LIB_FROM_TESTS = $(WORKSPACE_TESTS) --no-run --quiet && cp -p $(abspath $(TARGET_DIR))/debug/deps/libayllu_c.a \
	$(abspath $(TARGET_DIR))/debug/deps/libayllu_c.so $(abspath $(TARGET_DIR))/debug/
C_TEST_BUILDS = DEBUG_LIB_BUILD="$(C_LIB_FROM_TESTS)" TOOL_BUILD="$(WORKSPACE_TESTS) --no-run --quiet" \
	TEAM_TEST="$(abspath scripts/workspace-test) library --"
# Two phases. The builds, one after another (each already uses both cores). Then every suite at
# once: most of their time is waiting (robot processes on real clocks, a browser, sockets), so
# they overlap; each suite's output is printed whole when it ends (-O). The table at the end
# gives each suite's own wall and CPU seconds under the phase's.
test:
	@$(STEP) start
	$(STEP) "install test tools" env PYTHON=$(PYTHON) scripts/install-test-tools
	$(STEP) "build: Rust tests and the tool" $(WORKSPACE_TESTS) --no-run
	$(STEP) "build: Python venv and package" env PYTHON=$(PYTHON) scripts/python-venv
	$(STEP) "build: C (AylluLite, libayllu's tests, ASan)" $(MAKE) --no-print-directory build-c-tests
	$(STEP) "build: the core under ASan (nightly)" $(MAKE) --no-print-directory test-asan ASAN_BUILD_ONLY=1
	@echo "make test: running every suite at once; each one's output is printed when it ends"
	$(STEP) group "run: every suite at once" $(MAKE) --no-print-directory -j -O $(TEST_SUITES)
	@$(STEP) report

TEST_SUITES = suite-rust suite-rust-doc suite-c suite-lite-c suite-lite-python suite-conformance suite-python suite-asan
.PHONY: build-c-tests $(TEST_SUITES)
build-c-tests:
	$(MAKE) -C lite/c all
	$(MAKE) -C crates/ayllu-c all $(C_TEST_BUILDS)
suite-rust:
	@$(STEP) "Rust: unit, rule, property, processes" scripts/workspace-test --all -- --test-threads=$(TEST_THREADS)
suite-rust-doc:
	@$(STEP) "Rust: doc tests (build and run)" $(CARGO) test --workspace --exclude ayllu-ros2 --doc
suite-c:
	@$(STEP) "libayllu C (ASan), the C team" $(MAKE) -C crates/ayllu-c test $(C_TEST_BUILDS)
suite-lite-c:
	@$(STEP) "AylluLite C" $(MAKE) -C lite/c test
suite-lite-python:
	@$(STEP) "AylluLite Python" env AYLLU_BIN=$(TARGET_DIR)/debug/ayllu $(PYTHON) -m pytest lite/python/tests -q
suite-conformance:
	@$(STEP) "conformance (spec/conformance)" $(PYTHON) spec/conformance --ayllu $(TARGET_DIR)/debug/ayllu
suite-python:
	@$(STEP) "Python package" $(MAKE) --no-print-directory test-python
suite-asan:
	@$(STEP) "the core under ASan" $(MAKE) --no-print-directory test-asan

## The core's tests that reach ports through remembered addresses (crates/ayllu-core/src/sequence.rs,
## NodeCore::deliver_to) and run process bodies through borrowed pointers, under AddressSanitizer:
## a stale address is a use after free there. Needs rustup's nightly toolchain (the sanitizer flag
## is unstable): installs it (minimal profile) if missing, and fails naming it if that cannot be
## done; AYLLU_SKIP=asan skips it on purpose, loudly. About a minute; its own target directory.
## ASAN_BUILD_ONLY=1 only builds (make test builds first and runs with the other suites).
test-asan:
	@if ! $(CARGO) +nightly --version >/dev/null 2>&1; then \
		case ",$$AYLLU_SKIP," in *,asan,*) echo "*** SKIPPED: test-asan (AYLLU_SKIP=asan): the core's pointer paths were NOT run under ASan ***"; exit 0;; esac; \
		echo "test-asan: installing rustup's nightly toolchain (the sanitizer flag is unstable)"; \
		rustup toolchain install nightly --profile minimal || { echo "test-asan: no nightly toolchain and it could not be installed (rustup toolchain install nightly); AYLLU_SKIP=asan skips this on purpose" >&2; exit 1; }; \
	fi; \
	RUSTFLAGS="-Zsanitizer=address" CARGO_TARGET_DIR=$(abspath $(TARGET_DIR))/asan $(CARGO) +nightly test \
		-p ayllu-core --target x86_64-unknown-linux-gnu --test rules $(if $(ASAN_BUILD_ONLY),--no-run,-- receive_cache:: remote:: \
		structure:: structure_from_process:: process_periodic:: process_triggered::)

## The book (docs/, mkdocs.yml): concepts, tutorials, troubleshooting and the references, built
## into target/book (open target/book/index.html) with the API references under api/ (rustdoc,
## the C headers, pdoc); redraws docs/img from runs. `make lint` checks its links (--strict).
docs:
	PYTHON=$(PYTHON) CARGO=$(CARGO) scripts/book/build

## Formatting, lints and API docs, warnings as errors.
lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --workspace --exclude ayllu-ros2 --all-targets -- -D warnings
	RUSTDOCFLAGS=-Dwarnings $(CARGO) doc --workspace --exclude ayllu-ros2 --no-deps --quiet
	$(MAKE) -C crates/ayllu-c lint
	PYTHON=$(PYTHON) scripts/install-test-tools
	cd lite/python && $(PYTHON) -m ruff check . && $(PYTHON) -m ruff format --check .
	$(PYTHON) -m ruff check spec/conformance && $(PYTHON) -m ruff format --check spec/conformance
	$(MAKE) lint-python
	PYTHON=$(PYTHON) scripts/book/build --check

## Benchmarks (not part of the tests): figures printed beside a baseline measured in the same run.
bench:
	$(CARGO) bench -p ayllu --bench propagation

## libayllu: a port write and a process activation from C beside the same from Rust, same run.
bench-c:
	$(MAKE) -C crates/ayllu-c bench

## Network benchmarks (loopback UDP), each beside a raw-UDP baseline from the same run.
bench-net:
	$(CARGO) bench -p ayllu --bench network

## Raw UDP, Ayllu, Cyclone DDS, LCM, ZeroMQ and Zenoh side by side: round trip and one-way rate,
## same payloads, pinning and two-process layout, one table of ratios to raw UDP (ROUNDS=5). Installs
## LCM, ddsperf and ZeroMQ from Debian, builds the C peers and a Zenoh peer (its own target
## directory: the first build takes 5-10 min); then about 3 min (benches/peers/run).
bench-peers:
	CARGO=$(CARGO) benches/peers/run

## The zenoh:// transport (crates/ayllu-zenoh, docs/zenoh.md): its own cargo project and target
## directory (target/zenoh), never part of `make test`; the first build takes 5-10 min.
ZENOH_CARGO = cd crates/ayllu-zenoh && CARGO_TARGET_DIR=$(abspath $(TARGET_DIR))/zenoh $(CARGO)
zenoh:
	$(ZENOH_CARGO) build --release --features tool

## Its lints and tests (nodes in one process and as processes, routers, the bridge, conformance,
## TLS and access control, network namespaces when root; about 45 s once built): the
## workspace's `make lint` does not see this project.
test-zenoh:
	$(ZENOH_CARGO) fmt -- --check
	$(ZENOH_CARGO) clippy --release --all-targets -- -D warnings
	$(ZENOH_CARGO) clippy --release --all-targets --features tool -- -D warnings
	$(ZENOH_CARGO) test --release --features tool

## Ayllu over zenoh:// (peer mode, and clients of a router) beside udp:// and raw UDP, same run:
## round trip and one-way rate, with ratios (about 30 s once built; docs/zenoh.md, "Measured").
bench-zenoh:
	$(ZENOH_CARGO) test --release --features tool --test zenoh_bench -- --ignored --nocapture

## ROS 2 body (crates/ayllu-ros2, docs/ros2.md)
## A workspace member the default commands leave out (its DDS stack is ~110 more crates), built
## with the cargo feature `ros2` of the C and Python bindings into its own target directory
## (target/ros2), so neither build overwrites the other's artifacts.

ROS2_CARGO = CARGO_TARGET_DIR=$(abspath $(TARGET_DIR))/ros2 $(CARGO)

## The `ayllu` tool with the ROS 2 body (target/ros2/release/ayllu: `node --ros2`, `sim robot
## --ros2`, `sim serve --ros2`) and libayllu with it (ros2-c below). About 3 min the first time.
ros2:
	$(ROS2_CARGO) build --release -p ayllu-cli --features ros2
	$(MAKE) ros2-c

## The ROS 2 body's lints and tests: the crate's own (message types and golden CDR bytes, the
## mapping file, two bodies over RustDDS), the tool's against an independent ROS 2 stack
## (Cyclone DDS from Python: a robot driven for a minute, bad input, CMOMMT over ROS 2 in
## network namespaces with 10 % loss), the Python peer's own tests, and the C library's.
## Needs root (every test makes its own network namespace); installs cyclonedds from PyPI and
## nftables. About 8 min once built.
test-ros2:
	PYTHON=$(PYTHON) scripts/install-ros2-test-tools
	$(ROS2_CARGO) fmt --all -- --check
	$(ROS2_CARGO) clippy -p ayllu-ros2 -p ayllu-cli -p ayllu-c --features ayllu-cli/ros2,ayllu-c/ros2 --all-targets -- -D warnings
	RUSTDOCFLAGS=-Dwarnings $(ROS2_CARGO) doc -p ayllu-ros2 --no-deps --quiet
	$(ROS2_CARGO) test -p ayllu-ros2
	$(ROS2_CARGO) test -p ayllu-cli --features ros2 --test tool -- ros2_robot:: ros2_bad_input:: ros2_cmommt::
	cd crates/ayllu-ros2/tests/ros2_peer && $(PYTHON) -m ruff check . && $(PYTHON) -m ruff format --check . \
		&& $(PYTHON) -m pytest -q
	$(MAKE) ros2-c

## A port -> topic -> port round trip through two ROS 2 bodies beside the same through RustDDS
## alone (waiting on readiness, and polled at the body's period), same run; about 30 s once
## built; needs root (its own network namespace). Figures in docs/performance.md.
bench-ros2:
	$(ROS2_CARGO) bench -p ayllu-ros2 --bench round_trip

## libayllu with the ROS 2 body (`ay_ros2_body`, `ayInitRos2Body`), Fig. 2 on a ROS 2 robot
## (examples/cmommt/c/cmommt.c with -DAYLLU_ROS2_BODY) compiled against it with -Wall -Werror, and the C test of a wrong
## mapping file's message run against it (crates/ayllu-c's `make ros2`; no DDS is started).
ros2-c:
	$(MAKE) -C crates/ayllu-c ros2 TARGET_DIR=$(abspath $(TARGET_DIR))

## The Python module with the ROS 2 body (`Node.install_ros2_body`), installed by `maturin
## develop` (release, cargo's output in target/ros2) into the project's venv (scripts/python-venv),
## then tests/test_ros2.py run against it. Under the venv's lock, the install stamp is removed
## first, so the next `make test-python` or `make lint-python` puts the default wheel back (what
## they test) even if this install fails halfway.
ros2-python:
	@PY=$$(PYTHON=$(PYTHON) scripts/python-venv) && VENV=$$(dirname "$$(dirname "$$PY")") \
		&& flock -w 1200 "$${TMPDIR:-/tmp}/ayllu-python-venv.lock" sh -c ' \
			rm -f "$$1/.ayllu-installed" \
			&& VIRTUAL_ENV="$$1" PATH="$$1/bin:$$PATH" CARGO_TARGET_DIR="$$2" "$$1/bin/python" -m maturin develop \
				--release --features ros2 --manifest-path crates/ayllu-py/Cargo.toml' \
			sh "$$VENV" $(abspath $(TARGET_DIR))/ros2 \
		&& cd crates/ayllu-py && AYLLU_TEST_ROS2=1 $$PY -m pytest -q tests/test_ros2.py

## Simulation speed against real time (10, 100, 1000 robots, BLE and Random; the 1000-robot team
## also on every CPU), with a verdict per goal that this host's noise cannot fake (about 2 min);
## then instructions and last-level misses per robot-tick under Callgrind (scripts/sim-counts,
## 15 s), which every host counts alike.
bench-sim:
	$(CARGO) bench -p ayllu-sim --bench speed
	scripts/sim-counts

## The faulted team (network namespaces joined by the userspace shaper: delay, jitter,
## reordering, duplication; 30 % loss and partitions by nftables; kills and restarts) for
## MINUTES, checking take-overs, memory, descriptors and double claims (needs root, ip, nft, tun).
MINUTES ?= 60
soak:
	scripts/install-test-tools
	SOAK_MINUTES=$(MINUTES) $(CARGO) test --release -p ayllu-cli --test tool cross_subsumption_processes::soak -- --ignored --nocapture

## The rolling flight recorder for MINUTES (default 10) on a real node process talking UDP to
## another, keeping its last 60 s: bounded files, replayed bit for bit from its oldest checkpoint.
soak-recorder:
	AYLLU_ROLLING_MINUTES=$(or $(RECORDER_MINUTES),10) $(CARGO) test -p ayllu-cli --test tool rolling_recording::ten_minutes -- --ignored --nocapture

## Fuzz every target (decoder, node, recordings, udp:// URLs, command lines) for SECONDS each (needs a
## nightly toolchain; installs cargo-fuzz), then AylluLite C's decoders (a datagram, a datagram
## into a lite node, a URL) under clang's libFuzzer (installs Debian's clang).
SECONDS ?= 60
fuzz:
	fuzz/run $(SECONDS)
	scripts/install-c-fuzzer
	$(MAKE) -C lite/c fuzz SECONDS=$(SECONDS)

## Every fuzz target for RUNS executions each (default 10 million; about an hour each for
## node_receive and cli_args), JOBS targets at once, then DATAGRAMS mutated golden vectors over
## real UDP into two live `ayllu node` processes on loopback (at most 15 minutes; the example
## crates/ayllu-cli/examples/live_wire_mutation.rs). BUDGET=SECONDS stops the fuzz targets by
## then, wherever they got (e.g. on a machine shared with builds).
RUNS ?= 10000000
JOBS ?= 2
DATAGRAMS ?= 2000000
BUDGET ?=
fuzz-long:
	FUZZ_RUNS=$(RUNS) FUZZ_JOBS=$(JOBS) FUZZ_BUDGET=$(BUDGET) fuzz/run
	$(CARGO) build --release -p ayllu-cli --bin ayllu --example live_wire_mutation
	target/release/examples/live_wire_mutation target/release/ayllu --datagrams $(DATAGRAMS)

fmt:
	$(CARGO) fmt --all

## The Python package (crates/ayllu-py): `pip install ./crates/ayllu-py` into a venv under the
## target dir (reused while up to date: scripts/python-venv), then its pytest suite (the rule
## tests from Python, the simulator, sweeps, the examples and the guide's code).
test-python:
	@PY=$$(PYTHON=$(PYTHON) scripts/python-venv) && cd crates/ayllu-py \
		&& AYLLU_BIN=$(abspath $(TARGET_DIR))/debug/ayllu $$PY -m pytest -q tests

## The sweep on a Ray cluster (crates/ayllu-py/cluster_tests): installs Ray into the test venv
## first (a large install, hence not in `make test`; the Dask cluster's twin is).
test-ray:
	@PY=$$(PYTHON=$(PYTHON) scripts/python-venv) && $$PY -m pip install --quiet ray \
		&& cd crates/ayllu-py && $$PY -m pytest -q cluster_tests

## ruff and mypy (strict) on the Python package, its tests, the Python examples, the book's
## tutorials and its picture scripts (one file at a time: every tutorial is a main.py).
lint-python:
	@PY=$$(PYTHON=$(PYTHON) scripts/python-venv --tools-only) && cd crates/ayllu-py \
		&& $$PY -m ruff check --config pyproject.toml . ../../examples/cmommt/python ../../examples/tutorial ../../scripts/book ../ayllu-cli/tests/tool/fixtures \
		&& $$PY -m ruff format --config pyproject.toml --check . ../../examples/cmommt/python ../../examples/tutorial ../../scripts/book ../ayllu-cli/tests/tool/fixtures \
		&& MYPYPATH=../../examples/cmommt/python $$PY -m mypy python/ayllu tests bench ../../examples/cmommt/python \
		&& for f in ../../examples/tutorial/*/main.py ../../scripts/book/*.py ../ayllu-cli/tests/tool/fixtures/*.py; do \
			MYPYPATH=../../lite/python:python $$PY -m mypy --strict --no-error-summary $$f || exit 1; done

## Python benchmarks (not part of the tests): a port write, a process activation and a
## simulation step from Python, each beside a plain Python function call timed in the same run
## (the package reinstalled from a release build first, as a user's `pip install` makes it).
bench-python:
	@PY=$$(PYTHON=$(PYTHON) AYLLU_PY_PROFILE=release scripts/python-venv) && $$PY crates/ayllu-py/bench/bench.py
