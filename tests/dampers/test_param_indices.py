"""Force laws reach parameters by name: every model module's P_<NAME> constants match its dataclass's field order,
and a kernel's cache key covers only its own model's files."""
import inspect
import sys

import pytest

from mrd_env.stepping import codegen
from mrd_env.dampers import available_dampers, damper_class


@pytest.mark.parametrize("model", available_dampers())
def test_index_constants_match_field_order(model):
    cls = damper_class(model)
    module = sys.modules[cls.__module__]
    for i, name in enumerate(cls.Params.names()):
        const = f"P_{name.upper()}"
        assert getattr(module, const, None) == i, (
            f"{cls.__module__}.{const} must be {i}; regenerate the line with {cls.Params.__name__}.index_constants():\n"
            f"{cls.Params.index_constants()}")
    source = inspect.getsource(module)
    assert "p[0]" not in source and "p[1]" not in source  # no positional parameter access left


def test_kernel_cache_key_covers_only_the_models_own_files(tmp_path, monkeypatch):
    """Editing one model must recompile only its kernel: the key hashes the shared stepping files and the model's
    own modules (followed through its imports inside the damper package), never another model's file."""
    files = {m: codegen.model_modules(damper_class(m)) for m in available_dampers()}
    sd = {f.rsplit("/", 1)[-1] for f in files["spencer_dyke"]}
    assert "spencer_dyke.py" in sd and "hysteresis.py" in sd and "base.py" in sd
    assert not sd & {"bouc_wen.py", "bingham.py", "dahl.py", "lugre.py"}
    for m, fs in files.items():
        own = inspect.getsourcefile(damper_class(m))
        text = open(own, encoding="utf-8").read()
        # another model's file only when this model reuses its functions (dominguez: the bi-viscous curve)
        others = {inspect.getsourcefile(damper_class(o)) for o in available_dampers() if o != m}
        foreign = {f for f in fs & others if f"from .{f.rsplit('/', 1)[-1][:-3]} import" not in text}
        assert own in fs and not foreign, (m, foreign)
    # and the key changes with the model's own file, not with another's: each read from an editable copy
    real = codegen.model_modules
    copies = {}
    for m in ("bingham", "dahl"):
        own = inspect.getsourcefile(damper_class(m))
        copies[own] = tmp_path / f"{m}.py"
        copies[own].write_text(open(own, encoding="utf-8").read(), encoding="utf-8")
    monkeypatch.setattr(codegen, "model_modules", lambda cls: {str(copies.get(f, f)) for f in real(cls)})
    bingham = damper_class("bingham")
    key = codegen.kernel_source(bingham)[1]
    assert codegen.kernel_source(bingham)[1] == key
    (tmp_path / "dahl.py").write_text((tmp_path / "dahl.py").read_text() + "\n# edited\n")
    assert codegen.kernel_source(bingham)[1] == key
    (tmp_path / "bingham.py").write_text((tmp_path / "bingham.py").read_text() + "\n# edited\n")
    assert codegen.kernel_source(bingham)[1] != key
