"""fitode: the unknown constants of a known ODE, from a video."""
__version__ = "0.1.0"


def fit(*args, **kwargs):
    """See fitode.api.fit (imported lazily so `import fitode` does not load torch)."""
    from fitode.api import fit as _fit
    return _fit(*args, **kwargs)


def __getattr__(name):
    if name == "FitResult":
        from fitode.train.result import FitResult
        return FitResult
    raise AttributeError(name)
