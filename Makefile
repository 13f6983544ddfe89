# dhoit: every target a person runs, and the ones CI runs.
# One build profile (release) for runs, tests and benchmarks, so target/ is built once.

CARGO ?= cargo
RUN := $(CARGO) run --release --quiet --
# Real glTF scenes for tests and evaluation, read in place (never copied into the repository).
export DHOIT_SCENES ?= $(abspath ../shared/scenes)

.PHONY: all setup demo test fmt lint check bench build

all: demo

setup:
	@./scripts/setup.sh

build: setup
	$(CARGO) build --release

## The main job on built-in data: render a built-in scene with every CPU method, print a table.
demo: setup
	$(RUN) compare --scene particles --res 640x480 --budget 2fpp --out out/demo

fmt:
	$(CARGO) fmt --all -- --check

lint:
	$(CARGO) clippy --release --workspace --all-targets -- -D warnings

check: fmt lint

## Every check and every test.
test: setup fmt lint
	./scripts/test.sh

## Throughput of every pass, as JSON (also written to out/bench.json).
bench: setup
	$(RUN) bench --out out/bench.json
