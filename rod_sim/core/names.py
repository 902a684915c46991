"""Names of the models and integrators, importable without numba or scipy (for command-line
choices and parameter descriptors); the registries in models.py and integrators.py use them."""

MODEL_NAMES = ("full", "reduced", "rigid")
SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
INTEGRATOR_NAMES = ("dop853-jit", "radau-jit", "rk4", "rk2", "euler") + SCIPY_METHODS
