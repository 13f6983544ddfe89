# The peer of `dhoit bench --network-only`'s training step (issue: training throughput):
# the same 12-128-64-1 network (ReLU, ReLU, sigmoid), MSE + L1 on the first layer's weights +
# L2 on the second's, SGD with momentum 0.9, batch 512, in Keras 3 on JAX (CPU): model.fit over
# one million rows after a compile warm-up. Not part of the build or the tests; to run it:
#   python3 -m venv /tmp/keras && /tmp/keras/bin/pip install "jax[cpu]" keras
#   /tmp/keras/bin/python scripts/keras_peer.py
import os, time
os.environ["KERAS_BACKEND"] = "jax"
import numpy as np, keras
from keras import layers, regularizers

rng = np.random.default_rng(1)
x = rng.random((1_000_000, 12), dtype=np.float32)
y = rng.random((1_000_000, 1), dtype=np.float32)
model = keras.Sequential([
    keras.Input((12,)),
    layers.Dense(128, activation="relu", kernel_regularizer=regularizers.L1(1e-6)),
    layers.Dense(64, activation="relu", kernel_regularizer=regularizers.L2(1e-5)),
    layers.Dense(1, activation="sigmoid"),
])
model.compile(optimizer=keras.optimizers.SGD(1e-3, momentum=0.9), loss="mse")
model.fit(x[:51200], y[:51200], batch_size=512, epochs=1, verbose=0)  # compile warm-up
best = 0.0
for _ in range(3):
    t = time.perf_counter()
    model.fit(x, y, batch_size=512, epochs=1, verbose=0, shuffle=True)
    best = max(best, len(x) / (time.perf_counter() - t))
print(f"keras {keras.__version__} on jax: {best:.0f} samples/s (fastest of 3 epochs)")
