"""The core: errors, input checks, parameters, units, text tables, the process contract, composite models, state-space blocks and generic wavelet-variance theory. It imports nothing else from stochmod."""

__all__: list[str] = []
