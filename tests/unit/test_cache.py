"""The on-disk cache of preprocessing results (roughvib._cache) and its users: a hit returns the
computed floats exactly, any change of input or code misses, a broken file is recomputed, the
cache can be switched off, and it never fails a run."""

import json
import threading

import pytest

from roughvib import _cache
from roughvib._cache import cached_values, code_fingerprint
from roughvib.physics.friction import calibrate_force_amplitude, calibrated_force_amplitude
from roughvib.scene import Friction

CODE = {"sources": {"x.py": "0" * 64}, "python": "3", "machine": "m"}
# floats whose decimal forms are traps: not representable, subnormal, signed zero, huge
AWKWARD = {"a": 0.1 + 0.2, "b": 5e-324, "c": -0.0, "d": 1.7976931348623157e308,
           "e": 0.9153599563724701}


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGHVIB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("ROUGHVIB_CACHE", raising=False)
    return tmp_path / "cache"


class Counter:
    def __init__(self, values):
        self.values, self.calls = values, 0

    def __call__(self):
        self.calls += 1
        return dict(self.values)


def _files(cache):
    return sorted(p for p in cache.rglob("*") if p.is_file())


def test_a_hit_returns_the_computed_floats_bit_for_bit(cache):
    compute = Counter(AWKWARD)
    got, status = cached_values("k", {"x": 1.0}, compute, code=CODE)
    assert (status, compute.calls) == ("miss", 1)
    again, status = cached_values("k", {"x": 1.0}, compute, code=CODE)
    assert (status, compute.calls) == ("hit", 1)
    for name, v in AWKWARD.items():
        assert again[name].hex() == v.hex() == got[name].hex(), name
    assert len(_files(cache)) == 1


@pytest.mark.parametrize("inputs,code", [
    ({"x": 1.0000000000000002}, CODE),            # one ulp
    ({"x": 1.0, "y": None}, CODE),                # one more input
    ({"x": 1.0}, {**CODE, "sources": {"x.py": "1" * 64}}),   # the code changed
    ({"x": 1.0}, {**CODE, "numba": "9.9"}),      # a library changed
])
def test_any_change_of_input_or_code_misses(cache, inputs, code):
    cached_values("k", {"x": 1.0}, Counter({"v": 1.0}), code=CODE)
    compute = Counter({"v": 2.0})
    got, status = cached_values("k", inputs, compute, code=code)
    assert (status, compute.calls, got) == ("miss", 1, {"v": 2.0})
    assert cached_values("k", {"x": 1.0}, Counter({"v": 3.0}), code=CODE) == ({"v": 1.0}, "hit")


@pytest.mark.parametrize("damage", [
    lambda text: "",                                    # empty (a crash before any byte)
    lambda text: text[: len(text) // 2],                # truncated
    lambda text: "not json at all",
    lambda text: json.dumps({"values": {"v": "0x1p+0"}}),   # no key
    lambda text: text.replace("0x1.0000000000000p+0", "nonsense"),   # a bad float
    lambda text: text.replace("0x1.0000000000000p+0", "inf"),        # not finite
    lambda text: json.dumps({**json.loads(text), "values": {}}),     # no values
    lambda text: text.replace('"x": 1.0', '"x": 2.0'),  # another input's entry at this name
])
def test_a_corrupt_file_is_recomputed_and_rewritten(cache, damage):
    cached_values("k", {"x": 1.0}, Counter({"v": 1.0}), code=CODE)
    (path,) = _files(cache)
    path.write_text(damage(path.read_text()))
    compute = Counter({"v": 1.0})
    assert cached_values("k", {"x": 1.0}, compute, code=CODE) == ({"v": 1.0}, "miss")
    assert compute.calls == 1
    assert cached_values("k", {"x": 1.0}, compute, code=CODE) == ({"v": 1.0}, "hit")


@pytest.mark.parametrize("word", ["off", "0", "no", "FALSE"])
def test_the_cache_can_be_switched_off(cache, monkeypatch, word):
    monkeypatch.setenv("ROUGHVIB_CACHE", word)
    compute = Counter({"v": 1.0})
    for _ in range(2):
        assert cached_values("k", {"x": 1.0}, compute, code=CODE) == ({"v": 1.0}, "off")
    assert compute.calls == 2 and not cache.exists()


def test_an_unusable_directory_costs_only_the_saving(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("ROUGHVIB_CACHE_DIR", str(blocker / "cache"))  # below a file
    compute = Counter({"v": 1.0})
    for _ in range(2):
        assert cached_values("k", {"x": 1.0}, compute, code=CODE) == ({"v": 1.0}, "miss")
    assert compute.calls == 2


def test_default_directory_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.delenv("ROUGHVIB_CACHE_DIR", raising=False)
    monkeypatch.delenv("ROUGHVIB_CACHE", raising=False)
    monkeypatch.setattr(_cache.sys, "platform", "linux")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert _cache.cache_dir() == tmp_path / "roughvib"


def test_concurrent_writers_and_readers_never_see_a_partial_file(cache):
    # sweep workers computing the same key at once: every reader gets the value or a miss,
    # never a wrong or partial one, and no temporary file is left behind
    results, errors = [], []

    def worker():
        try:
            for _ in range(40):
                results.append(cached_values("k", {"x": 1.0}, Counter(AWKWARD), code=CODE)[0])
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=worker) for _ in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert len(results) == 240 and all(r == AWKWARD for r in results)
    assert [p.name.endswith(".json") and not p.name.startswith(".tmp")
            for p in _files(cache)] == [True]


def test_code_fingerprint_changes_with_the_source(tmp_path):
    src = tmp_path / "m.py"
    src.write_text("x = 1\n")
    a = code_fingerprint([src])
    src.write_text("x = 2\n")
    b = code_fingerprint([src])
    assert a["sources"] != b["sources"] and {k: v for k, v in a.items() if k != "sources"} == \
        {k: v for k, v in b.items() if k != "sources"}
    assert a["numba"] and a["numpy"] and a["scipy"]


# --------------------------------------------------------------------------------------------
# the force calibration through the cache
# --------------------------------------------------------------------------------------------

ARGS = (0.01, 0.221, 0.5, 0.221 * 9.81, 2 * 3.141592653589793 * 7.0)


def test_cached_calibration_is_the_calibration_exactly(cache):
    fr = Friction()
    direct = calibrate_force_amplitude(*ARGS, fr)
    first, s1 = calibrated_force_amplitude(*ARGS, fr)
    second, s2 = calibrated_force_amplitude(*ARGS, fr)
    assert (s1, s2) == ("miss", "hit")
    assert first.hex() == second.hex() == direct.hex()
    # another friction law is another entry, with its own (larger) amplitude
    other, s3 = calibrated_force_amplitude(*ARGS, Friction(mu_stick=0.5))
    assert s3 == "miss" and other > direct
    assert len(_files(cache)) == 2


def test_a_run_reports_how_its_calibration_was_obtained(cache):
    import roughvib
    from roughvib.model.system import assemble

    scene = roughvib.load_scene("paper-handset", {"plate.max_frequency": 2000.0})
    first, second = assemble(scene), assemble(scene)
    assert (first.calibration["cache"], second.calibration["cache"]) == ("miss", "hit")
    assert first.force_amplitude.hex() == second.force_amplitude.hex()
