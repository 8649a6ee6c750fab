import numpy as np

from ext_sense.cli import main as ext_sense_main


def test_run_writes_the_documented_layout(tmp_path, capsys):
    out = tmp_path / "run"
    assert (
        ext_sense_main(
            [
                "sim",
                "run",
                "tap_rod30_nuskin_wire",
                "--out",
                str(out),
                "--trials",
                "3",
                "--seed",
                "5",
            ]
        )
        == 0
    )
    d = np.load(out / "dataset.npz")
    assert str(d["task"]) == "tap_localization"
    assert str(d["sensor"]) == "nuskin"
    assert str(d["label_kind"]) == "regression"
    assert d["y"].dtype == np.float64
    assert d["y"].shape == (3,)
    assert d["trial"].dtype == np.int32
    assert d["onset_ns"].dtype == np.int64
    assert np.all(d["rod_length_m"] == 0.3)
    n = d["ev_t_ns"].size
    for key, dtype in (
        ("ev_trial", np.int32),
        ("ev_t_ns", np.int64),
        ("ev_taxel", np.uint16),
        ("ev_polarity", np.int8),
        ("ev_value", np.uint16),
    ):
        assert d[key].dtype == dtype
        assert d[key].shape == (n,)
    assert np.all(np.diff(d["ev_trial"]) >= 0)
    tact = (out / "nuskin" / "trial_0000.tact").read_text().splitlines()
    assert tact[0].startswith("1 1 1 ")
    assert tact[-1].startswith("2 2 2 ")
    assert len(tact) - 2 == int((d["ev_trial"] == 0).sum())
    assert (out / "nuskin" / "essentials.csv").read_text().startswith("trial,file,label")
    raw = (out / "raw" / "nuskin.bin").read_bytes()
    assert len(raw) > 0
    assert (out / "raw" / "nuskin_chunks.csv").exists()
    assert "wire_faults" in (out / "run.json").read_text()


def test_raw_stream_decodes_to_the_events(tmp_path):
    from ext_sense_drivers.nuskin.wire import WordDecoder

    out = tmp_path / "run"
    assert (
        ext_sense_main(
            [
                "sim",
                "run",
                "handover_rod_nuskin",
                "--out",
                str(out),
                "--trials",
                "2",
                "--formats",
                "npz,raw",
            ]
        )
        == 0
    )
    d = np.load(out / "dataset.npz")
    got = WordDecoder().feed((out / "raw" / "nuskin.bin").read_bytes())
    np.testing.assert_array_equal(got.taxel, d["ev_taxel"])
    np.testing.assert_array_equal(got.value, d["ev_value"])


def test_biotac_run_and_list(tmp_path, capsys):
    out = tmp_path / "bt"
    assert (
        ext_sense_main(["sim", "run", "tap_rod30_biotac", "--out", str(out), "--trials", "2"]) == 0
    )
    d = np.load(out / "dataset.npz")
    assert d["pac"].shape[:2] == (2, 2)
    assert d["pac_t0_ns"].dtype == np.int64
    lines = (out / "biotac" / "biotac.csv").read_text().splitlines()
    assert lines[0].startswith("trial,sensor,t_s,pac")
    assert len(lines) == 1 + 2 * 2 * d["pac"].shape[2]
    from ext_sense_drivers.biotac.decoder import BridgeDecoder

    frames = BridgeDecoder().feed((out / "raw" / "biotac.bin").read_bytes())
    assert frames.n == 2 * 2 * d["pdc"].shape[2]
    assert ext_sense_main(["sim", "list"]) == 0
    listed = capsys.readouterr().out
    for name in ("tap_rod20_nuskin", "tap_rod50_nuskin", "food_fork_biotac", "handover_box_nuskin"):
        assert name in listed


def test_run_reports_a_bad_scene(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        "task: tap_localization\nsensor: nuskin\nobject: {length_m: 0.3, section: "
        "{shape: circle, diameter_m: 0.01}}\neffects: [contact_impulse, beam_modes]\n"
    )
    assert ext_sense_main(["sim", "run", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "nuskin_transduction" in capsys.readouterr().err


def test_bag_holds_packets_and_ground_truth(tmp_path):
    pytest = __import__("pytest")
    bags = pytest.importorskip("ext_sense_bags")
    out = tmp_path / "run"
    assert (
        ext_sense_main(
            [
                "sim",
                "run",
                "tap_rod20_nuskin",
                "--out",
                str(out),
                "--trials",
                "2",
                "--formats",
                "npz,bag",
            ]
        )
        == 0
    )
    from ext_sense_drivers.packets import make_decoder

    d = np.load(out / "dataset.npz")
    n_events, truths, decoder = 0, [], None
    with bags.BagReader(out / "bag") as reader:
        for record, msg in reader.messages():
            if record.topic == "/extsense/nuskin/packets":
                decoder = decoder or make_decoder(str(msg.encoding), str(msg.encoding_options))
                n_events += decoder.decode(msg).events.size
            else:
                truths.append(msg)
    assert n_events == d["ev_t_ns"].size
    assert decoder.counters.lost_packets == 0
    assert [t.trial for t in truths] == [0, 1]
    np.testing.assert_allclose([t.tap_position_m for t in truths], d["y"])


def test_serve_prints_its_pty_and_the_onsets(tmp_path):
    import subprocess
    import sys

    link = tmp_path / "port"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "ext_sense.cli",
            "sim",
            "serve",
            "nuskin",
            "--scene",
            "tap_rod20_nuskin",
            "--trials",
            "2",
            "--period",
            "0.3",
            "--link",
            str(link),
        ],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("sim serve nuskin: streaming scene tap_rod20_nuskin on /dev/")
    assert sum(line.startswith("trial ") for line in lines) == 2
    assert lines[-1].startswith("sent 2 trials")
    assert not link.exists()  # removed on close


def test_run_refuses_a_used_output_folder(tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    (out / "old.txt").write_text("x")
    assert (
        ext_sense_main(["sim", "run", "tap_rod20_nuskin", "--out", str(out), "--trials", "1"]) == 2
    )
    assert "must be new or empty" in capsys.readouterr().err
