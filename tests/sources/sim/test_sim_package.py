"""`from stereo_gui.sources.sim import NAME` works for every public name of the package's
modules (other code imported them from the one-module sim.py)."""

import importlib
import inspect
import pkgutil

import stereo_gui.sources.sim as sim


def test_every_public_name_is_importable_from_the_package():
    missing = []
    for info in pkgutil.iter_modules(sim.__path__):
        mod = importlib.import_module(f"{sim.__name__}.{info.name}")
        for name, obj in vars(mod).items():
            defined_here = getattr(obj, "__module__", mod.__name__) == mod.__name__
            if name.startswith("_") or inspect.ismodule(obj) or not defined_here:
                continue
            if name.isupper() or inspect.isclass(obj) or inspect.isfunction(obj):
                if getattr(sim, name, None) is not obj or name not in sim.__all__:
                    missing.append(f"{info.name}.{name}")
    assert not missing, missing
