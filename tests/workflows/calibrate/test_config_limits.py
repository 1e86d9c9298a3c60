"""CalibrationConfig refuses integer settings outside their ranges before anything runs, naming the option."""

from __future__ import annotations

import pytest

from bubblecal.workflows.calibrate import CalibrationConfig, CalibrationError


@pytest.mark.parametrize("field, value, option", [
    ("seed", -1, "--seed"), ("chunk_size", 0, "--chunk-size"), ("chunk_size", -3, "--chunk-size"),
    ("population", 10**23, "--population"), ("population", 1, "--population"), ("num_mcmc_steps", 0, "--mcmc-steps"),
    ("nuts_chains", 0, "--nuts-chains"), ("phase2_samples", 9, "--phase2-samples"), ("seed", 1.5, "--seed"),
    ("predictive_samples", 9, "--predictive-samples"), ("crps_replicates", 0, "--crps-replicates"),
])
def test_out_of_range_settings_name_the_option(field, value, option):
    with pytest.raises(CalibrationError, match=rf"{field} \({option}\) must be an integer in \["):
        CalibrationConfig(**{field: value})


def test_defaults_and_unset_optionals_pass():
    CalibrationConfig()
    CalibrationConfig(population=None, chunk_size=None, phase2_samples=None, seed=2**32 - 1)


def test_unusable_output_folders_are_named(tmp_path):
    from bubblecal.workflows.calibrate import make_plan

    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    with pytest.raises(CalibrationError, match="exists and is not a folder"):
        make_plan(CalibrationConfig(agents=("definity",), out=a_file))
    with pytest.raises(CalibrationError, match="is a file, so the folder cannot be made"):
        make_plan(CalibrationConfig(agents=("definity",), out=a_file / "sub"))


def test_data_dir_files_are_all_read_or_named(tmp_path):
    from bubblecal.workflows.calibrate import make_plan

    data = tmp_path / "data"
    data.mkdir()
    with pytest.raises(CalibrationError, match="holds none of the files this run reads"):
        make_plan(CalibrationConfig(agents=("definity",), data_dir=data, out=tmp_path / "o"))
    (data / "definity_compression_2.1um.csv").write_text("displacement_dpd,force_dpd\n0,0\n")
    (data / "Definity_Compression_2.9um_dpd.csv").write_text("displacement_dpd,force_dpd\n0,0\n")
    with pytest.raises(CalibrationError) as err:
        make_plan(CalibrationConfig(agents=("definity",), data_dir=data, out=tmp_path / "o"))
    msg = str(err.value)
    assert "definity_compression_2.1um.csv" in msg and "accepted names" in msg
    assert "Definity_Compression_2.9um_dpd.csv (did you mean definity_compression_2.9um_dpd.csv?)" in msg
