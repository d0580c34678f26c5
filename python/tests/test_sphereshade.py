"""The Python module against the command line (same library): arrays render
the PNG bytes and image hash the CLI renders for the same spheres as .xyzr;
trajectory loops equal fresh renders; bad input raises ValueError with the
CLI's message; the GIL is released while rendering; a Renderer shared by two
threads is safe; 100 renders keep memory bounded and leave no Vulkan leaks
under validation.

The CLI binary is target/debug/sphereshade (built by `cargo test`), or
SPHERESHADE_BIN.
"""

import json
import os
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import sphereshade

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"


def cli():
    b = os.environ.get("SPHERESHADE_BIN", str(ROOT / "target" / "debug" / "sphereshade"))
    if not Path(b).exists():
        pytest.fail(f"{b} is missing: run `cargo build` (cargo test builds it) or set SPHERESHADE_BIN")
    return b


def spheres(n=400, seed=3):
    rng = np.random.default_rng(seed)
    p = (rng.random((n, 3)) * 30.0).astype(np.float32)
    r = (0.8 + rng.random(n) * 1.2).astype(np.float32)
    return p, r


def write_xyzr(path, p, r, regions=None):
    with open(path, "w") as f:
        for i in range(len(p)):
            # %.9g round-trips float32 exactly
            cols = [f"{float(v):.9g}" for v in (*p[i], r[i])]
            if regions is not None:
                cols += [str(int(x)) for x in regions[i]]
            f.write(" ".join(cols) + "\n")


def run_cli(args):
    env = dict(os.environ, XDG_RUNTIME_DIR=os.environ.get("XDG_RUNTIME_DIR", "/tmp"))
    o = subprocess.run([cli(), *args], capture_output=True, text=True, env=env)
    assert o.returncode == 0, o.stderr
    return o


@pytest.mark.parametrize("aov", ["color", "id"])
def test_arrays_render_like_the_cli(tmp_path, aov):
    p, r = spheres()
    regions = np.stack([np.arange(len(p)) // 100, np.arange(len(p)) // 10], axis=1).astype(np.uint32)
    xyzr = tmp_path / "s.xyzr"
    write_xyzr(xyzr, p, r, regions)
    png, js = tmp_path / "cli.png", tmp_path / "cli.json"
    run_cli(["render", str(xyzr), "--width", "96", "--height", "72", "--aov", aov,
             "--out", str(png), "--json", str(js)])
    img = sphereshade.render(p, r, regions=regions, width=96, height=72, aov=aov)
    assert img.shape == (72, 96, 4) and img.dtype == np.uint8
    assert sphereshade.encode_png(img) == png.read_bytes()
    assert sphereshade.image_sha256(img) == json.loads(js.read_text())["image_sha256"]


def test_publication_options_render_like_the_cli(tmp_path):
    # supersampling, tiles, a transparent background and outlines take the
    # CLI's render path too
    p, r = spheres()
    xyzr = tmp_path / "s.xyzr"
    write_xyzr(xyzr, p, r, None)
    png = tmp_path / "cli.png"
    opts = ["--ssaa", "2", "--tile-size", "32", "--background", "transparent", "--outline", "1"]
    run_cli(["render", str(xyzr), "--width", "96", "--height", "72", *opts, "--out", str(png)])
    img = sphereshade.render(p, r, width=96, height=72, ssaa=2, tile_size=32,
                             background="transparent", outline=1)
    assert sphereshade.encode_png(img) == png.read_bytes()
    assert 0 < (img[..., 3] == 0).sum() < img.shape[0] * img.shape[1]


def test_trajectory_loop_equals_fresh_renders():
    p, r = spheres(300)
    frames = [p + np.float32(0.7 * k) * np.sin(p).astype(np.float32) for k in range(3)]
    camera = dict(view_center=(15, 15, 15), view_height=50)
    rr = sphereshade.Renderer(frames[0], r, width=80, height=60, camera=camera)
    for f in frames:
        rr.set_positions(f)
        looped = rr.render()
        fresh = sphereshade.render(f, r, width=80, height=60, camera=camera)
        assert np.array_equal(looped, fresh)
    t = rr.timings
    assert "raster" in t and "shade" in t and all(v >= 0 for v in t.values())
    rr.close()


def test_load_and_trajectory_readers():
    s = sphereshade.load(DATA / "1tii.pdb")
    assert len(s) == 5684
    assert s.positions.shape == (5684, 3) and s.positions.dtype == np.float32
    assert s.radii.shape == (5684,) and s.colors.shape == (5684, 4)
    assert s.regions.shape == (5684, 4) and s.level_names == ["model", "chain", "residue", "atom"]
    t = sphereshade.Trajectory(DATA / "traj" / "adk_dims.dcd")
    assert len(t) == 98 and t.atoms == 3341
    assert abs(t.time(97) - 98.0) < 1e-3
    np.testing.assert_allclose(t[0][0], [11.736, 8.501, -10.445], atol=6e-4)
    with pytest.raises(IndexError):
        t[98]


def test_load_takes_the_cli_colour_and_rules(tmp_path):
    # the same scheme and rules as the CLI, in order: hidden spheres are
    # gone, alpha lands in the colours, and the render is the CLI's
    rules = ["--color", "chain", "--hide", "chain D", "--alpha", "chain A=0.4",
             "--paint", "resname TRP=yellow"]
    s = sphereshade.load(DATA / "1tii.pdb", color="chain",
                         rules=[("hide", "chain D"), ("alpha", "chain A=0.4"),
                                ("paint", "resname TRP=yellow")])
    full = sphereshade.load(DATA / "1tii.pdb")
    assert 0 < len(s) < len(full)
    assert set(np.unique(s.colors[:, 3])) == {102, 255}
    assert (s.colors[:, :3] == [240, 220, 30]).all(axis=1).any()  # "yellow"
    png = tmp_path / "cli.png"
    opts = ["--width", "96", "--height", "72", "--shadows", "deep", "--ssdo", "off"]
    run_cli(["render", str(DATA / "1tii.pdb"), *rules, *opts, "--out", str(png)])
    img = sphereshade.render(s.positions, s.radii, s.colors, width=96, height=72,
                             shadows="deep", ssdo="off")
    assert sphereshade.encode_png(img) == png.read_bytes()
    # keyword shorthands equal the rules list
    t = sphereshade.load(DATA / "1tii.pdb", color="chain", hide="chain D",
                         alpha=["chain A=0.4"], paint="resname TRP=yellow")
    assert (t.colors == s.colors).all()
    for kw, msg in [(dict(hide="chain"), "column"), (dict(alpha="chain A=2"), "2"),
                    (dict(color="rainbow"), "rainbow"), (dict(rules=[("tint", "all")]), "tint"),
                    (dict(colormap="jet"), "jet")]:
        with pytest.raises(ValueError, match=msg):
            sphereshade.load(DATA / "1tii.pdb", **kw)


@pytest.mark.parametrize("call, message", [
    (lambda p, r: sphereshade.render(p[:, :2], r), "shape (N, 3)"),
    (lambda p, r: sphereshade.render(p.astype(np.int32), r), "float32 or float64"),
    (lambda p, r: sphereshade.render(p, r[:10]), "10 radii for 400 positions"),
    (lambda p, r: sphereshade.render(np.where(p > 29, np.nan, p), r), "not finite"),
    (lambda p, r: sphereshade.render(p, -r), "must be a finite number > 0"),
    (lambda p, r: sphereshade.render(p, r, shadows="bogus"), "invalid value 'bogus' for '--shadows"),
    (lambda p, r: sphereshade.render(p, r, issm_t="x"), "--issm-t"),
    (lambda p, r: sphereshade.render(p, r, opacity=1.5), "--opacity must be between 0 and 1"),
    (lambda p, r: sphereshade.render(p, r, width=0), "--width/--height must be between"),
    (lambda p, r: sphereshade.render(p, r, no_such_option=1), "--no-such-option"),
    (lambda p, r: sphereshade.render(p, r, colors=np.zeros((400, 3), np.uint8)), "shape (N, 4)"),
])
def test_bad_input_is_a_value_error_with_the_cli_message(call, message):
    p, r = spheres()
    with pytest.raises(ValueError) as e:
        call(p, r)
    assert message in str(e.value)
    assert "\n" not in str(e.value)


def test_set_positions_checks_its_input():
    p, r = spheres(50)
    rr = sphereshade.Renderer(p, r, width=32, height=24)
    with pytest.raises(ValueError, match="50 spheres"):
        rr.set_positions(p[:10])
    with pytest.raises(ValueError, match="not finite"):
        rr.set_positions(np.full_like(p, np.inf))
    rr.close()
    with pytest.raises(RuntimeError, match="closed"):
        rr.render()


def test_the_gil_is_released_while_rendering():
    p, r = spheres(20000)
    rr = sphereshade.Renderer(p, r, width=640, height=480)
    rr.render()  # pipelines made
    ticks = [0]
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            ticks[0] += 1
            time.sleep(0.001)

    t = threading.Thread(target=spin)
    t.start()
    before = ticks[0]
    started = time.perf_counter()
    rr.render()
    took = time.perf_counter() - started
    during = ticks[0] - before
    stop.set()
    t.join()
    rr.close()
    # the other thread ran throughout the render (sleeps of 1 ms: at least
    # a tenth of the possible ticks, whatever the machine's speed)
    assert during >= max(3, int(took * 1000 * 0.1)), (during, took)


def test_one_renderer_shared_by_two_threads():
    p, r = spheres(500)
    rr = sphereshade.Renderer(p, r, width=64, height=48)
    want = rr.render()
    out, errors = [], []

    def work():
        try:
            for _ in range(5):
                out.append(rr.render())
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(e)

    ts = [threading.Thread(target=work) for _ in range(2)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert not errors and len(out) == 10
    assert all(np.array_equal(o, want) for o in out)
    rr.close()


def rss_mib():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return 0.0


def test_many_renders_keep_memory_bounded_and_leak_nothing():
    p, r = spheres(2000)
    for _ in range(10):
        sphereshade.render(p, r, width=64, height=48)
    base = rss_mib()
    for _ in range(90):
        sphereshade.render(p, r, width=64, height=48)
    grown = rss_mib() - base
    # Stated bound: 32 MiB over 90 renders (each makes and frees a device).
    assert grown < 32, f"RSS grew {grown:.1f} MiB over 90 renders"
    rr = sphereshade.Renderer(p, r, width=64, height=48, validate=True)
    for _ in range(3):
        rr.render()
    assert rr.validation_messages == 0
    # leak reports at device destruction are counted too
    assert rr.close() == 0


def test_image_wrapper_for_notebooks(tmp_path):
    p, r = spheres(100)
    img = sphereshade.Image(sphereshade.render(p, r, width=40, height=30))
    png = img._repr_png_()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    img.save(tmp_path / "x.png")
    assert (tmp_path / "x.png").read_bytes() == png
    assert np.asarray(img).shape == (30, 40, 4)
