"""Settings of ``nonrigid diagnose`` from experiment.toml's ``[diagnose]`` table and the command
line (options override the table; both checked, an unknown key names the nearest), and
experiment.toml's own keys: a misspelt key is an error naming the nearest, ``[meta]`` is free.

No diagnosis runs here: each check stops before the first solve.
"""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from refine.bundle import Bundle, Experiment, Observations, RectangleDomain, read_bundle, write_bundle
from refine.cli.diagnose import OPTIONS, settings_given, settings_of
from refine.cli.main import build_parser, main
from refine.diagnosis import DiagnoseConfig
from refine.exceptions import BundleError, SettingsError

EXAMPLES = Path(__file__).resolve().parents[2] / "shared" / "examples"


def _bundle(path, extra):
    x, y = np.meshgrid(np.arange(0.0, 31.0, 10.0), np.arange(0.0, 21.0, 10.0))
    reference = np.stack([x.ravel(), y.ravel()], axis=1)
    roles = np.where((x.ravel() % 30 == 0) | (y.ravel() % 20 == 0), "boundary", "guide")
    experiment = Experiment(name="tiny", kind="plane-stress", domain=RectangleDomain(0.0, 0.0, 30.0, 20.0),
                            law="neo-hookean", E=1.0, nu=0.3, thickness=1.0, extra=extra)
    write_bundle(path, Bundle(experiment, Observations(np.arange(1, 13), reference, roles,
                                                       0.01 * reference[None])))
    return path


def test_options_override_the_table_which_overrides_the_defaults(tmp_path):
    path = _bundle(tmp_path / "b", {"diagnose": {"seed": 5, "max_regions": 1, "try_laws": False, "alpha": 0.01},
                                    "meta": {"operator": "lt"}})
    bundle = read_bundle(path)
    args = build_parser().parse_args(["diagnose", str(path), "--out", str(tmp_path / "o"), "--seed", "7", "--laws",
                                      "--linear-solver", "superlu", "--try-rectangles", "auto", "--h", "2.5",
                                      "--significance", "0.002"])
    cfg = settings_of(bundle, settings_given(args))
    expected = dataclasses.replace(DiagnoseConfig(), seed=7, max_regions=1, try_laws=True, alpha=0.002,
                                   linear_solver="superlu", try_rectangles=None, h=2.5)
    assert cfg == expected
    assert settings_of(bundle) == dataclasses.replace(DiagnoseConfig(), seed=5, max_regions=1, try_laws=False,
                                                      alpha=0.01)
    assert bundle.experiment.extra["meta"] == {"operator": "lt"}


def test_every_setting_has_one_option():
    names = [name for _, name, _ in OPTIONS]
    assert sorted(names) == sorted(f.name for f in dataclasses.fields(DiagnoseConfig))


@pytest.mark.parametrize("table,message", [
    ({"max_region": 1}, "unknown setting 'max_region' (did you mean 'max_regions'?)"),
    ({"sed": 1}, "unknown setting 'sed' (did you mean 'seed'?)"),
    ({"max_regions": 1.5}, "max_regions must be an integer >= 1, got 1.5"),
    ({"linear_solver": "kul"}, "linear_solver 'kul' is unknown (did you mean 'klu'?)"),
])
def test_a_bad_table_is_an_error_of_the_command(tmp_path, capsys, table, message):
    path = _bundle(tmp_path / "b", {"diagnose": table})
    with pytest.raises(SettingsError) as caught:
        settings_of(read_bundle(path))
    assert message in str(caught.value) and "experiment.toml [diagnose]" in str(caught.value)
    assert main(["diagnose", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("nonrigid diagnose: error:") and message in err
    assert not (tmp_path / "o").exists()  # refused before anything was written


def test_a_bad_option_value_is_an_error_of_the_command(tmp_path, capsys):
    path = _bundle(tmp_path / "b", {})
    assert main(["diagnose", str(path), "--out", str(tmp_path / "o"), "--alpha", "2"]) == 2
    assert "alpha must be a number in [0, 1) (0: never reject the initial model), got 2.0" in capsys.readouterr().err


@pytest.mark.parametrize("line,section,nearest", [
    ("thicknes = 1.0", "model", "model.thickness"),
    ("noise_sd = 0.02", "measurement", "measurement.noise_std"),
    ("noise_std = 0.02", "model", "measurement.noise_std"),  # the right key in the wrong table
])
def test_a_misspelt_key_in_experiment_toml_names_the_nearest(tmp_path, line, section, nearest):
    path = _bundle(tmp_path / "b", {})
    toml = (path / "experiment.toml").read_text()
    if f"[{section}]" not in toml:
        toml += f"\n[{section}]\n"
    (path / "experiment.toml").write_text(toml.replace(f"[{section}]\n", f"[{section}]\n{line}\n"))
    with pytest.raises(BundleError, match="did you mean") as caught:
        read_bundle(path)
    assert f"(did you mean '{nearest}'?)" in str(caught.value) and "[meta]" in str(caught.value)


def test_the_example_bundle_still_reads():
    if not (EXAMPLES / "sheet-stiff-inclusion" / "bundle").is_dir():
        pytest.skip("../shared/examples is absent (the example bundle from an independent simulator)")
    b = read_bundle(EXAMPLES / "sheet-stiff-inclusion" / "bundle")
    assert b.experiment.noise_std == 0.02 and b.experiment.thickness == 1.0 and b.experiment.extra == {}


def test_a_batch_reads_each_bundles_own_diagnose_table(tmp_path):
    """refine.batch gives each bundle its [diagnose] table under the batch's settings: a misspelt
    key there is that bundle's error row (named), not silently the defaults."""
    from refine.batch.runner import diagnose_one

    path = _bundle(tmp_path / "b", {"diagnose": {"max_region": 1}})
    row = diagnose_one(str(path), str(tmp_path / "out" / "b"), {"workers": 1}, figures=False)
    assert row["error"]["type"] == "SettingsError"
    assert "did you mean 'max_regions'?" in row["error"]["message"]
