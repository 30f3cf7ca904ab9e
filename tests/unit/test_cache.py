"""The on-disk cache of preprocessing results (roughvib._cache) and its users: a hit returns the
computed floats exactly, any change of input or code misses, a broken file is recomputed, the
cache can be switched off, and it never fails a run."""

import threading

import numpy as np
import pytest

from roughvib import _cache
from roughvib._cache import array_digest, cached_arrays, cached_values, code_fingerprint
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


def _rewrite(path, **arrays):
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _key(path):
    with np.load(path) as f:
        return str(f["__key__"][()])


@pytest.mark.parametrize("damage", [
    lambda p: p.write_bytes(b""),                                  # a crash before any byte
    lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),   # truncated
    lambda p: p.write_bytes(b"not a zip file at all"),
    lambda p: _rewrite(p, v=np.float64(1.0)),                      # no key
    lambda p: _rewrite(p, __key__=np.array(_key(p))),              # no values
    lambda p: _rewrite(p, __key__=np.array(_key(p)), v=np.float64("nan")),   # not finite
    lambda p: _rewrite(p, __key__=np.array(_key(p)), v=np.array("1.0")),     # not a number
    lambda p: _rewrite(p, __key__=np.array(_key(p).replace('"x": 1.0', '"x": 2.0')),
                       v=np.float64(2.0)),                         # another input's entry
])
def test_a_corrupt_file_is_recomputed_and_rewritten(cache, damage):
    cached_values("k", {"x": 1.0}, Counter({"v": 1.0}), code=CODE)
    (path,) = _files(cache)
    damage(path)
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
    assert [p.suffix == ".npz" and not p.name.startswith(".tmp") for p in _files(cache)] == \
        [True]


def test_code_fingerprint_changes_with_the_source(tmp_path):
    src = tmp_path / "m.py"
    src.write_text("x = 1\n")
    a = code_fingerprint([src])
    src.write_text("x = 2\n")
    b = code_fingerprint([src])
    assert a["sources"] != b["sources"] and {k: v for k, v in a.items() if k != "sources"} == \
        {k: v for k, v in b.items() if k != "sources"}
    assert a["numba"] and a["numpy"] and a["scipy"]


def test_arrays_are_cached_exactly_and_keyed_by_their_digest(cache):
    z = np.random.default_rng(1).normal(size=1000)
    coeffs = {"c": np.outer(z, [1.0, 1 / 3, np.pi]), "n": np.arange(5)}
    compute = Counter(coeffs)
    first, s1 = cached_arrays("a", {"z": array_digest(z)}, compute, code=CODE)
    again, s2 = cached_arrays("a", {"z": array_digest(z)}, compute, code=CODE)
    assert (s1, s2, compute.calls) == ("miss", "hit", 1)
    for name, a in coeffs.items():
        assert again[name].dtype == a.dtype and again[name].tobytes() == a.tobytes()
    z2 = z.copy()
    z2[500] = np.nextafter(z2[500], np.inf)  # one ulp of one sample: another key
    assert array_digest(z2) != array_digest(z)
    assert cached_arrays("a", {"z": array_digest(z2)}, compute, code=CODE)[1] == "miss"


def test_a_kind_keeps_its_most_recently_used_files_within_its_budget(cache, monkeypatch):
    import os

    big = {"a": np.zeros(1000)}
    entry = {}
    for i in range(3):  # entries 0, 1, 2, used in that order, long ago
        before = set(_files(cache))
        cached_arrays("b", {"i": i}, Counter(big), code=CODE)
        (entry[i],) = set(_files(cache)) - before
        os.utime(entry[i], (1000.0 + i, 1000.0 + i))
    monkeypatch.setattr(_cache, "MAX_BYTES", sum(p.stat().st_size for p in entry.values()))
    assert cached_arrays("b", {"i": 0}, Counter(big), code=CODE)[1] == "hit"  # 0 used now
    cached_arrays("b", {"i": 3}, Counter(big), code=CODE)  # over budget: 1 goes
    assert not entry[1].exists() and entry[0].exists() and entry[2].exists()
    assert len(_files(cache)) == 3
    assert cached_arrays("b", {"i": 3}, Counter(big), code=CODE)[1] == "hit"


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


# --------------------------------------------------------------------------------------------
# the scipy-backed preprocessing through the cache: contact, polylog series, spline
# --------------------------------------------------------------------------------------------


def test_cached_contact_solution_is_the_solution_exactly(cache, monkeypatch):
    from roughvib.physics.surface import contact
    from roughvib.physics.surface.contact import _solve_contact_cached, solve_contact

    args = (2.16801, 1.2e8, 1.5e-4, 3.3e-6, 1.6e-3, 1.15e11)
    direct = solve_contact(*args, model="gw")
    calls = []
    monkeypatch.setattr(contact, "solve_contact",
                        lambda *a, **k: calls.append(a) or solve_contact(*a, **k))
    for _ in range(2):
        got = _solve_contact_cached(*args, "gw")
        assert got == direct and got.h.hex() == direct.h.hex()
    assert len(calls) == 1  # the second came from the file
    assert [p.parent.name for p in _files(cache)] == ["contact-solution"]
    with pytest.raises(ValueError, match="exceeds the range"):  # errors are not cached
        _solve_contact_cached(1e9, *args[1:], "gw")
    assert len(_files(cache)) == 1


def test_cached_polylog_coefficients_are_the_computed_ones(cache):
    from roughvib.physics import plate

    for s in (2, 3):
        plate._li_coefficients.cache_clear()
        first = plate._li_coefficients(s)
        plate._li_coefficients.cache_clear()
        again = plate._li_coefficients(s)  # from the file
        assert again.tobytes() == first.tobytes() == plate._li_coefficients_computed(s).tobytes()
    plate._li_coefficients.cache_clear()
    assert len(_files(cache)) == 2


@pytest.mark.parametrize("kind", ["cubic", "quintic"])
def test_cached_spline_coefficients_are_the_spline_exactly(cache, kind):
    from roughvib.physics.surface.interp import build_coefficients, cached_coefficients

    z = np.random.default_rng(3).normal(scale=1e-6, size=400)
    direct = build_coefficients(z, 1e-5, kind)
    first, s1 = cached_coefficients(z, 1e-5, kind)
    again, s2 = cached_coefficients(z, 1e-5, kind)
    assert (s1, s2) == ("miss", "hit")
    assert again.tobytes() == direct.tobytes() and again.shape == direct.shape
    assert again.flags.c_contiguous  # the layout numba compiled the kernels for
    assert cached_coefficients(z, 2e-5, kind)[1] == "miss"
    assert cached_coefficients(z, 1e-5, "linear")[1] == "not used"  # needs no scipy


# --------------------------------------------------------------------------------------------
# whole runs: the cache changes nothing but the time, and never fails a run
# --------------------------------------------------------------------------------------------

TINY_RUN = {"plate.max_frequency": 2000.0, "output.duration": 0.004,
            "solver.method": "adaptive-modal", "output.progress": False}


def _run_arrays(result):
    ds = result.dataset
    out = {name: ds[name].values.tobytes() for name in [*ds.data_vars, *ds.coords]}
    out["force_amplitude"] = result.summary["force_amplitude"].hex()
    out["events"] = result.events.to_csv(float_format="%.17g")
    return out


def _cache_states(result):
    return result.summary["calibration"].get("cache")


def test_a_run_is_bit_identical_with_and_without_the_cache(cache, monkeypatch):
    import warnings

    import roughvib
    from roughvib.physics import plate

    def run():
        plate._li_coefficients.cache_clear()  # in-process memo: read the file (or compute)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the short window's validity warnings
            return roughvib.simulate(roughvib.load_scene("paper", TINY_RUN))

    monkeypatch.setenv("ROUGHVIB_CACHE", "off")
    off = run()
    monkeypatch.delenv("ROUGHVIB_CACHE")
    cold, warm = run(), run()
    assert [_cache_states(r) for r in (off, cold, warm)] == ["off", "miss", "hit"]
    kinds = {p.parent.name for p in _files(cache)}
    assert {"force-calibration", "polylog-coefficients", "profile-interpolant"} <= kinds
    # every cache file damaged: computed again, the same numbers
    for p in _files(cache):
        p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2])
    damaged = run()
    assert _cache_states(damaged) == "miss"
    want = _run_arrays(off)
    for r in (cold, warm, damaged):
        assert _run_arrays(r) == want
    plate._li_coefficients.cache_clear()


def test_a_run_with_an_unwritable_cache_directory_succeeds(tmp_path, monkeypatch):
    import roughvib

    blocker = tmp_path / "file"  # a directory below a file can be neither made nor written,
    blocker.write_text("")  # even by root (who ignores permission bits)
    monkeypatch.setenv("ROUGHVIB_CACHE_DIR", str(blocker / "cache"))
    monkeypatch.delenv("ROUGHVIB_CACHE", raising=False)
    with pytest.warns(Warning):  # the short window's validity warnings
        result = roughvib.simulate(roughvib.load_scene("paper", TINY_RUN))
    assert result.ok and _cache_states(result) == "miss"
    assert blocker.read_text() == ""


def test_no_home_directory_or_unreadable_source_switches_the_cache_off(monkeypatch, tmp_path):
    monkeypatch.delenv("ROUGHVIB_CACHE_DIR", raising=False)
    monkeypatch.delenv("ROUGHVIB_CACHE", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setattr(_cache.sys, "platform", "linux")

    def no_home():
        raise RuntimeError("Could not determine home directory.")

    monkeypatch.setattr(_cache.Path, "home", staticmethod(no_home))
    assert _cache.cache_dir() is None
    compute = Counter({"v": 1.0})
    assert cached_values("k", {"x": 1.0}, compute, code=CODE) == ({"v": 1.0}, "off")
    # a source that cannot be read: a change of code could not be seen, so no cache
    monkeypatch.setenv("ROUGHVIB_CACHE_DIR", str(tmp_path / "cache"))
    code = code_fingerprint([tmp_path / "missing.py"])
    assert code is None
    assert cached_values("k", {"x": 1.0}, compute, code=code) == ({"v": 1.0}, "off")
    assert compute.calls == 2 and not (tmp_path / "cache").exists()
