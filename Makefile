# dhoit: every target a person runs, and the ones CI runs.
# One build profile (release) for runs, tests and benchmarks, so target/ is built once.

CARGO ?= cargo
RUN := $(CARGO) run --release --quiet --
# Real glTF scenes for tests and evaluation, read in place (never copied into the repository).
export DHOIT_SCENES ?= $(abspath ../shared/scenes)

.PHONY: all setup demo test fmt lint check bench frame devbin build train nets golden eval generalise trade versus fuzz pictures webgpu web web-picture web-record

all: demo

setup:
	@./scripts/setup.sh

# Building needs no setup (a Rust toolchain and a C++ compiler for nv-flip); `make setup`
# installs what the tests and the demo need (lavapipe, a font, g++), and they run it first.
build:
	$(CARGO) build --release

## The main job on built-in data: train the default network from the built-in scenes (about two
## minutes; the recipe of the committed data/weights.safetensors, which it leaves alone),
## then render a held-out built-in scene with it beside every baseline and print the tables.
demo: setup build
	$(RUN) train --out out/demo/weights.safetensors
	$(RUN) compare --scene particles --res 640x480 --budget 1fpp,2fpp --always-approximate --weights out/demo/weights.safetensors --out out/demo

## Train the default network from the built-in scenes: data/weights.safetensors, data/config.json,
## data/loss.svg, data/loss.png (the dataset is generated into data/generated/, which git ignores).
train: build
	$(CARGO) run --release --quiet -p dhoit-train

## Leave one family out: a network trained without each built-in family in turn, scored on
## that family's held-out scene against the optimal allocation, beside one trained on every
## family: docs/generalise.md, out/generalise/generalise.json. Every network at GENERALISE_SEEDS
## training seeds, each figure beside its seeds' range (about 15 minutes a seed on 2 cores).
GENERALISE_SEEDS ?= 3
generalise: build
	$(RUN) generalise --opacity 0.33 --seeds $(GENERALISE_SEEDS)

## The networks of other sizes shipped beside the default, trained on the same data:
## data/nets/H1-H2/weights.safetensors (+ config.json, loss plot). `dhoit trade` and `dhoit fit`
## compare them.
NETS := 16,8 32,16 64,32
nets: build
	@for h in $(NETS); do \
	  $(RUN) train --hidden $$h --out data/nets/$$(echo $$h | tr , -)/weights.safetensors || exit 1; \
	done

## Regression data for the committed weights: a small features file and its predictions.
golden: build
	$(RUN) features --scene hair --view 2 --res 160x120 --budget 2fpp --limit 512 --out data/golden/features.safetensors
	$(RUN) predict --weights data/weights.safetensors --input data/golden/features.safetensors --output data/golden/predictions.safetensors

## Quality on scenes never used for training: the ten papers' built-ins (seed 1) and, when
## present, the real scenes in $(DHOIT_SCENES), every surface at the papers' one opacity 0.33;
## then with their own materials, the five material families (seed 1) and the real scenes;
## budgets relative to each frame's fragments and in slots per pixel; once at equal F and once
## at equal bytes. At equal F each k-buffer renders its own approximation (--always-approximate)
## even where the exact A-buffer would need fewer bytes: what measures the methods; the bytes
## columns say what each would allocate. Small summaries -> docs/eval-slots.md, docs/eval-bytes.md,
## docs/eval-materials-slots.md, docs/eval-materials-bytes.md (the glass tinted, the default) and,
## the glass grey (--glass grey), docs/eval-materials-grey.md (committed), every frame,
## image and montage -> out/eval/; then the README's results table and docs/results.md's tables
## from them (scripts/results_table.py, which `make test` checks).
EVAL_BUILTIN := shells,spheres,foliage,plates,hair,particles,cad,glass,statue,shrub
EVAL_REAL := StanfordBunny/StanfordBunny.glb GlassVaseFlowers/GlassVaseFlowers.glb FlightHelmet/glTF/FlightHelmet.gltf ToyCar/glTF/ToyCar.gltf TransmissionTest/TransmissionTest.glb
EVAL_MATERIAL_BUILTIN := windows,covers,cards,smoke,strands
EVAL_MATERIAL_REAL := $(EVAL_REAL) AlphaBlendModeTest/AlphaBlendModeTest.glb TextureSettingsTest/TextureSettingsTest.glb GlassBrokenWindow/GlassBrokenWindow.glb
EVAL_BUDGETS := 10%,25%,50%,75%,90%,0.25fpp,0.5fpp,1fpp,2fpp,4fpp
EVAL_ARGS := --view 1,3 --res 320x240 --budget $(EVAL_BUDGETS) --methods fkb,vkb,dkb,optimal,optimal-pooled,mlab,wboit,mboit,linked-list
eval: build
	@scenes="$(EVAL_BUILTIN)"; materials="$(EVAL_MATERIAL_BUILTIN)"; \
	if [ -d "$(DHOIT_SCENES)" ]; then \
	  for f in $(EVAL_REAL); do scenes="$$scenes,$(DHOIT_SCENES)/$$f"; done; \
	  for f in $(EVAL_MATERIAL_REAL); do materials="$$materials,$(DHOIT_SCENES)/$$f"; done; \
	else echo "eval: no real scenes at $(DHOIT_SCENES): the built-in scenes only" >&2; fi; \
	$(RUN) compare --scene "$$scenes" $(EVAL_ARGS) --opacity 0.33 --equal slots --always-approximate --out out/eval/slots --summary docs/eval-slots.md && \
	$(RUN) compare --scene "$$scenes" $(EVAL_ARGS) --opacity 0.33 --equal bytes --out out/eval/bytes --summary docs/eval-bytes.md && \
	$(RUN) compare --scene "$$materials" $(EVAL_ARGS) --equal slots --always-approximate --out out/eval/materials-slots --summary docs/eval-materials-slots.md && \
	$(RUN) compare --scene "$$materials" $(EVAL_ARGS) --equal bytes --out out/eval/materials-bytes --summary docs/eval-materials-bytes.md && \
	$(RUN) compare --scene "$$materials" $(EVAL_ARGS) --glass grey --equal slots --always-approximate --out out/eval/materials-grey --summary docs/eval-materials-grey.md && \
	python3 scripts/results_table.py --write

## The README's pictures of per-fragment materials: alpha-textured leaf cards and a
## stained-glass pane, the A-buffer, VKB and DKB side by side at 10% of the fragments
## (640x480) -> docs/materials-cards.png, docs/materials-windows.png; and the glass assets of
## $(DHOIT_SCENES) from their own viewpoints beside their screenshots -> docs/asset-*.png.
pictures: build
	$(RUN) compare --scene cards,windows --view 3 --res 640x480 --budget 10% --methods vkb,dkb --always-approximate --out out/pictures
	cp "out/pictures/cards_v3_10%_montage.png" docs/materials-cards.png
	cp "out/pictures/windows_v3_10%_montage.png" docs/materials-windows.png
	@# Each glass asset from its own viewpoint (--camera asset) beside the screenshot it ships:
	@# the A-buffer, and DKB at 25% of the fragments, the glass tinted. Left out, and said, where the
	@# scenes are absent.
	@for a in "TransmissionTest TransmissionTest.glb screenshot.png 480x312" \
	          "GlassVaseFlowers GlassVaseFlowers.glb screenshot.jpg 400x386" \
	          "GlassBrokenWindow GlassBrokenWindow.glb screenshot.jpg 400x402" \
	          "AlphaBlendModeTest AlphaBlendModeTest.glb screenshot.jpg 640x197"; do \
	  set -- $$a; \
	  if [ ! -f "$(DHOIT_SCENES)/$$1/$$2" ]; then echo "pictures: $$1 left out (not in $(DHOIT_SCENES))"; continue; fi; \
	  $(RUN) compare --scene "$(DHOIT_SCENES)/$$1/$$2" --camera asset --glass tinted --res $$4 --budget 25% \
	    --methods dkb --always-approximate --beside "$(DHOIT_SCENES)/$$1/$$3" --out out/pictures || exit 1; \
	  cp "out/pictures/$${1}_v0_25%_montage.png" "docs/asset-$$1.png"; \
	done

## The speed-accuracy trade of the shipped networks on the evaluation scenes: importance-pass
## time (GPU timestamps on the adapter at hand, at 640x480) against MSE and FLIP (320x240),
## the Pareto front marked. Small form -> docs/trade.json, docs/trade.md, docs/trade.svg and
## docs/trade.png (all scenes); every scene's plot -> out/trade/.
TRADE_BUDGETS := 10%,25%,50%,75%,90%
trade: build
	@scenes="$(EVAL_BUILTIN)"; \
	if [ -d "$(DHOIT_SCENES)" ]; then \
	  for f in $(EVAL_REAL); do scenes="$$scenes,$(DHOIT_SCENES)/$$f"; done; \
	else echo "trade: no real scenes at $(DHOIT_SCENES): the built-in scenes only" >&2; fi; \
	$(RUN) trade --scene "$$scenes" --view 1,3 --res 320x240 --budget $(TRADE_BUDGETS) --opacity 0.33 --precision f32,f16 --time-res 640x480 --out out/trade --summary docs
	python3 scripts/results_table.py --write

## Every OIT method at equal bytes (the A-buffer, FKB, VKB, DKB, WBOIT, MBOIT, the budgeted
## linked list) on the evaluation scenes at one opacity, one memory M for all (0.25 to 1 times
## each frame's exact A-buffer bytes), DKB with the default network and with each shipped in
## data/nets/ (all at f16, each network's weights in its memory): GPU frame time (timestamps
## on the adapter at hand) against MSE and FLIP, one chart a memory, the Pareto front marked ->
## docs/versus.md, docs/versus.json, docs/versus_*.svg/png.
versus: build
	@scenes="$(EVAL_BUILTIN)"; \
	if [ -d "$(DHOIT_SCENES)" ]; then \
	  for f in $(EVAL_REAL); do scenes="$$scenes,$(DHOIT_SCENES)/$$f"; done; \
	else echo "versus: no real scenes at $(DHOIT_SCENES): the built-in scenes only" >&2; fi; \
	$(RUN) versus --scene "$$scenes" --view 1 --res 320x240 --memory 0.25,0.5,0.75,1 --opacity 0.33 \
	  --networks $$(ls data/nets/*/weights.safetensors | paste -sd,) --precision f16 \
	  --out out/versus --summary docs
	python3 scripts/results_table.py --write

## Long structured fuzzing of every file parser (glTF/GLB, weights, features, dumps): the
## property tests of tests/fuzz.rs with FUZZ_CASES mutated inputs each (CI runs 128). Keep
## any input that fails under tests/corpus/.
FUZZ_CASES ?= 2000000
fuzz: build
	PROPTEST_CASES=$(FUZZ_CASES) $(CARGO) test --release --test fuzz -- --nocapture --test-threads 2

fmt:
	$(CARGO) fmt --all -- --check

lint:
	$(CARGO) clippy --release --workspace --all-targets -- -D warnings
	@if $(CARGO) tree -p dhoit-train -e normal --prefix none | grep -qE '^(wgpu|naga|pollster) '; then \
	  echo "lint: dhoit-train depends on wgpu: keep dhoit-runtime's gpu feature off for it" >&2; exit 1; fi

check: fmt lint

## Every check and every test.
test: setup fmt lint
	./scripts/test.sh

## Throughput of every pass, as JSON (also written to out/bench.json).
bench: setup
	$(RUN) bench --out out/bench.json

## The frame a real-time renderer records: every method's GPU frame on the deep built-in scenes
## at 640x480, at 25% and at 1 fpp (DKB, in two geometry passes and in three, against the exact
## A-buffer and VKB), then an orbit of 120 frames at 320x240 at 1 fpp and at 25% (frames a
## second one at a time and two in flight, dhoit's waits, temporal change, bytes against each
## frame's own A-buffer; a camera four times as fast for the A-buffer, VKB and DKB).
## The tables in docs/frame/ (and on stderr), JSON in out/frame/; docs/results.md copies them.
## About 90 minutes on lavapipe; FRAME_RES=1920x1080 for the large frames.
FRAME_SCENES ?= particles,shells,hair,foliage
FRAME_RES ?= 640x480
frame: setup
	mkdir -p out/frame
	$(RUN) bench --gpu-only --res $(FRAME_RES) --budget 25% --scenes $(FRAME_SCENES) --out out/frame/$(FRAME_RES)-25.json --summary docs/frame/$(FRAME_RES)-25.md
	$(RUN) bench --gpu-only --res $(FRAME_RES) --budget 1fpp --scenes $(FRAME_SCENES) --out out/frame/$(FRAME_RES)-1fpp.json --summary docs/frame/$(FRAME_RES)-1fpp.md
	$(RUN) bench --gpu-only --res 320x240 --budget 1fpp --scenes $(FRAME_SCENES) --sequence 120 --out out/frame/orbit-320x240-1fpp.json --summary docs/frame/orbit-320x240-1fpp.md
	$(RUN) bench --gpu-only --res 320x240 --budget 25% --scenes $(FRAME_SCENES) --sequence 120 --out out/frame/orbit-320x240-25.json --summary docs/frame/orbit-320x240-25.md
	python3 scripts/results_table.py --write

## WebGPU: dhoit-runtime built for wasm32 with wgpu's WebGPU backend, then every pipeline of the
## methods WebGPU runs (all but MBOIT, which needs float32-blendable) created on Dawn, Chrome's
## WebGPU, over a private Mesa 25 lavapipe (scripts/dawn.sh), with a device as a page gets one;
## then the web page's frames there against the native ones, and the page in a headless
## Chromium (scripts/web.sh test). `make test` runs it too.
webgpu: setup
	./scripts/webgpu.sh

## The web page (examples/web): DKB, VKB and the A-buffer side by side in a browser, the budget a
## slider. Builds its wasm and serves it on http://localhost:8000.
web:
	./scripts/web.sh serve

## The page's picture, docs/web.png: a screenshot of it in a headless Chromium.
web-picture:
	./scripts/web.sh picture

## The web build's figures, docs/web-measured.md (which docs/web.md copies): its test's frames
## against the native ones, and its times on Dawn and in Chromium.
web-record: setup
	./scripts/web.sh record

## For a machine lent with a real GPU: the release binary and the GPU test binaries (stripped)
## into .devbin/ and the Vulkan loader package into .gl/ (both ignored by git), which
## scripts/device.sh runs the bench and the tests with there.
devbin: build
	mkdir -p .devbin .gl
	strip -o .devbin/dhoit target/release/dhoit
	for t in dhoit-runtime:gpu dhoit-runtime:extremes dhoit:equivalence; do \
	  strip -o .devbin/test-$${t#*:} $$($(CARGO) test --release -p $${t%%:*} --test $${t#*:} --no-run --message-format=json 2>/dev/null | \
	    python3 -c 'import json,sys; print([m["executable"] for m in map(json.loads, sys.stdin) if m.get("executable") and m["target"]["kind"] == ["test"]][0])') || exit 1; done
	pwd > .devbin/built-in
	cd .gl && apt-get download libvulkan1 libglvnd0 libegl1 libopengl0 libgl1 libglx0 libgles2
