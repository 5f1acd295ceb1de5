"""Temperature and time columns, the IPA UR10 export, the bundled ur10-ipa set and the
report's residual against temperature and time."""

import numpy as np
import pytest

import kinecal
from kinecal.cli import main
from kinecal.datasets import DATASETS, bundled_csv
from kinecal.errors import InputError
from kinecal.io.conditions import seconds_of
from kinecal.io.ipa_export import convert_ipa_export, read_ipa_export

#: two rows as the upstream export writes them (series A's header; ';', decimal commas)
EXPORT = (
    "Timestamp;Goal x;Goal y;Goal z;Goal roll;Goal pitch;Goal yaw;shoulder_pan_joint;"
    "shoulder_lift_joint;elbow_joint;wrist_1_joint;wrist_2_joint;wrist_3_joint;"
    "measurement_temperature;measurement_x;measurement_y;measurement_z;measurement_rx;"
    "measurement_ry;measurement_rz\n"
    "20200714163904;0,365141;-0,000212669;1,4273;1,57002;1,57007;1,57073;-1,5708;-1,5708;"
    "0,0;-1,5708;0,0;0,0;23,6800003051758;2361,9831;-1368,5474;119,39713;-90,409151;"
    "-59,885105;-90,887438\n"
    "20200714163924;0,8;0,6;0,9;1,7453299999999998;1,5708;1,5708;-2,14055;-2,08493;"
    "-0,837441;-0,218756;0,393594;-0,00187856;23,6800003051758;1685,2797;-1665,3456;"
    "-415,81103;-90,282663;-49,675357;-90,926009\n")


def test_seconds_of_numbers_and_iso_dates():
    assert seconds_of("12.5") == 12.5
    assert seconds_of("1970-01-01T00:01:00") == 60.0  # no zone: UTC
    assert seconds_of("1970-01-01T02:00:00+02:00") == 0.0
    assert seconds_of("yesterday") is None and seconds_of("nan") is None


def test_measurements_carry_temperature_and_time(tmp_path):
    m = kinecal.load_model("ur5")
    path = tmp_path / "m.csv"
    path.write_text("q1,q2,q3,q4,q5,q6,x,y,z,temperature,time\n"
                    "0,-90,90,0,90,0,1,2,3,21.5,2020-07-14T16:39:04\n"
                    "10,-80,80,0,90,0,1,2,3,21.75,2020-07-14T16:39:14\n")
    d = kinecal.read_measurements(path, m)
    np.testing.assert_array_equal(d.temperature, [21.5, 21.75])
    assert d.time[1] - d.time[0] == 10.0
    sub = d.subset(np.array([1]))
    assert sub.temperature[0] == 21.75 and sub.time[0] == d.time[1]
    path.write_text(path.read_text().replace("21.75", "warm"))
    with pytest.raises(InputError, match="row 2: column temperature"):
        kinecal.read_measurements(path, m)
    path.write_text(path.read_text().replace("warm", "21.75").replace(
        "2020-07-14T16:39:14", "later"))
    with pytest.raises(InputError, match="row 2: column time"):
        kinecal.read_measurements(path, m)


def test_ipa_export_converts_units_and_columns(tmp_path):
    src = tmp_path / "measurements_grid.csv"
    src.write_text(EXPORT)
    cols = read_ipa_export(src)
    np.testing.assert_allclose(cols["q1"], np.degrees([-1.5708, -2.14055]), rtol=1e-11)
    np.testing.assert_array_equal(cols["x"], [2361.9831, 1685.2797])
    np.testing.assert_array_equal(cols["c"], [-90.887438, -90.926009])
    assert list(cols["time"]) == ["2020-07-14T16:39:04", "2020-07-14T16:39:24"]
    assert "sx" not in cols  # series A has no standard deviations
    assert main(["import", str(src), "--out", str(tmp_path / "A.csv"), "--quiet"]) == 0
    d = kinecal.read_measurements(tmp_path / "A.csv", kinecal.load_model("ur5"))
    assert d.time[1] - d.time[0] == 20.0 and d.temperature[0] == pytest.approx(23.68)
    assert d.rotations is None  # positions only, unless asked
    assert main(["import", str(src), "--out", str(tmp_path / "A6.csv"), "--orientation",
                 "--quiet"]) == 0
    d6 = kinecal.read_measurements(tmp_path / "A6.csv", kinecal.load_model("ur5"),
                                   "intrinsic-xyz:deg")
    from scipy.spatial.transform import Rotation

    np.testing.assert_allclose(d6.rotations[0], Rotation.from_euler(
        "XYZ", [-90.409151, -59.885105, -90.887438], degrees=True).as_matrix(), atol=1e-12)
    # a spreadsheet-rounded timestamp (series B-D) leaves the time out, the rows in order
    src.write_text(EXPORT.replace("20200714163904", "2,02011E+13"))
    assert "time" not in read_ipa_export(src)
    src.write_text(EXPORT.replace("2361,9831", "n/a"))
    with pytest.raises(InputError, match="row 1: column measurement_x"):
        convert_ipa_export(src, tmp_path / "bad.csv")
    assert not (tmp_path / "bad.csv").exists()


def test_bundled_ur10_series_and_model(tmp_path, monkeypatch):
    assert DATASETS["ur10-ipa"]["license"] == "MIT"
    model = kinecal.load_model(bundled_csv("ur10-ipa:model"))
    a = kinecal.read_measurements("ur10-ipa:A", model)
    b = kinecal.read_measurements("ur10-ipa:B", model)
    assert len(a) == 11911 and len(b) == 1495
    assert a.time is not None and b.time is None and b.temperature is not None
    assert b.sigma is not None and a.rotations is None and b.rotations is None
    b6 = kinecal.read_measurements("ur10-ipa:B-tmac", model, "intrinsic-xyz:deg")
    assert b6.rotations is not None and b6.sigma.shape == (1495, 6)
    assert np.all(np.diff(a.time[:100]) > 0)
    # Trafo_TM_F: the flange in the T-Mac frame; the T-Mac in the flange frame is then
    # -R^T t, the model's tool point (0, 0, 109) mm
    from kinecal.datasets import dataset_dir

    T = np.loadtxt(dataset_dir("ur10-ipa") / "A-trafo-init.txt")
    np.testing.assert_allclose(-T[:3, :3].T @ T[:3, 3], model.tool, atol=0.01)
    monkeypatch.chdir(tmp_path)
    assert main(["datasets", "ur10-ipa"]) == 0
    assert (tmp_path / "ur10-ipa-LICENSE.txt").read_text().startswith("MIT License")
    assert (tmp_path / "A-trafo-init.txt").exists() and (tmp_path / "ur10-tmac.yaml").exists()


def test_report_plots_the_residual_against_temperature_and_time(tmp_path):
    from kinecal.calibration.serial.simulate import simulate
    from kinecal.io.measurements import write_measurements

    ur5 = kinecal.load_model("ur5")
    sim = simulate(ur5, 60, errors="random", noise=0.01, rng=3)
    data = sim.data
    import dataclasses

    data = dataclasses.replace(data, temperature=np.linspace(20.0, 23.0, 60),
                               time=np.arange(60.0) * 30.0)
    write_measurements(tmp_path / "c.csv", data, ur5)
    assert main(["calibrate", "ur5", str(tmp_path / "c.csv"), "--report",
                 str(tmp_path / "r.html"), "--quiet"]) == 0
    html = (tmp_path / "r.html").read_text()
    assert "Residual against temperature and time" in html and 'id="fig-conditions"' in html
    assert "20 .. 23 deg C" in html and "0 .. 0.4917 h" in html
    res = kinecal.calibrate(ur5, data)
    assert set(res.conditions) == {"temperature", "time"}
