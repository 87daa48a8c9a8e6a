# The project's commands. `make demo` and `make test` are the README's two commands;
# CI (.ci/run) runs `make lint` and `make test`.
CARGO ?= cargo

.PHONY: demo test lint bench fmt

## Run the main demo: the paper's cross-subsumption, 3 robots x 4 targets, with a robot failure.
demo:
	$(CARGO) run --release --quiet --example cross_subsumption

## Run every test (unit, rule, property, examples).
test:
	$(CARGO) test --workspace

## Formatting and lints, warnings as errors.
lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --workspace --all-targets -- -D warnings

## Benchmarks (not part of the tests): figures printed beside a baseline measured in the same run.
bench:
	$(CARGO) bench -p ayllu --bench propagation

fmt:
	$(CARGO) fmt --all
