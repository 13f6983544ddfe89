# dhoit: every target a person runs, and the ones CI runs.
# One build profile (release) for runs, tests and benchmarks, so target/ is built once.

CARGO ?= cargo
RUN := $(CARGO) run --release --quiet --
# Real glTF scenes for tests and evaluation, read in place (never copied into the repository).
export DHOIT_SCENES ?= $(abspath ../shared/scenes)

.PHONY: all setup demo test fmt lint check bench build train golden eval

all: demo

setup:
	@./scripts/setup.sh

build: setup
	$(CARGO) build --release

## The main job on built-in data: train the default network from the built-in scenes (about two
## minutes; the same weights as the committed data/weights.safetensors, which it leaves alone),
## then render a held-out built-in scene with it beside every baseline and print the tables.
demo: build
	$(RUN) train --out out/demo/weights.safetensors
	$(RUN) compare --scene particles --res 640x480 --budget 1fpp,2fpp --weights out/demo/weights.safetensors --out out/demo

## Train the default network from the built-in scenes: data/weights.safetensors, data/config.json,
## data/loss.png (the dataset is generated into data/generated/, which git ignores).
train: build
	$(CARGO) run --release --quiet -p dhoit-train

## Regression data for the committed weights: a small features file and its predictions.
golden: build
	$(RUN) features --scene hair --view 2 --res 160x120 --budget 2fpp --limit 512 --out data/golden/features.safetensors
	$(RUN) predict --weights data/weights.safetensors --input data/golden/features.safetensors --output data/golden/predictions.safetensors

## Quality table on scenes never used for training: the built-ins (seed 1) and ../shared/scenes.
EVAL_SCENES := spheres,plates,particles,hair,foliage,shells,$(DHOIT_SCENES)/StanfordBunny/StanfordBunny.glb,$(DHOIT_SCENES)/GlassVaseFlowers/GlassVaseFlowers.glb,$(DHOIT_SCENES)/FlightHelmet/glTF/FlightHelmet.gltf,$(DHOIT_SCENES)/ToyCar/glTF/ToyCar.gltf,$(DHOIT_SCENES)/TransmissionTest/TransmissionTest.glb
eval: build
	$(RUN) compare --scene $(EVAL_SCENES) --view 1,3 --res 320x240 --budget 0.25fpp,0.5fpp,1fpp,2fpp,4fpp --methods fkb,vkb,dkb,optimal,mlab --out out/eval

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
