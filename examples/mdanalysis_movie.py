"""Renders a molecular-dynamics trajectory to PNG frames from Python.

    python examples/mdanalysis_movie.py TOPOLOGY TRAJECTORY OUTDIR [--frames N]

With MDAnalysis installed (`pip install MDAnalysis`) the trajectory is read
by MDAnalysis (any format it reads); without it, by sphereshade's own
readers (.xtc .trr .dcd .lammpstrj, multi-model .pdb, ...). Either way the
frames go through one sphereshade.Renderer: `set_positions` uploads only
the coordinates, `render` returns the image as a numpy array.

Example with the test data of this repository:

    python examples/mdanalysis_movie.py tests/data/traj/adk_oplsaa.gro \\
        tests/data/traj/adk_oplsaa.xtc /tmp/adk --frames 10
"""

import argparse
import os
import sys
import time

import numpy as np

import sphereshade


def frames_mdanalysis(top, traj, n):
    import MDAnalysis as mda  # optional

    u = mda.Universe(top, traj)
    for k, ts in enumerate(u.trajectory[:n]):
        yield k, u.atoms.positions.astype(np.float32), ts.time


def frames_sphereshade(traj, n):
    t = sphereshade.Trajectory(traj)
    for k in range(min(n, len(t))):
        yield k, t[k], t.time(k)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("topology")
    ap.add_argument("trajectory")
    ap.add_argument("outdir")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=720)
    a = ap.parse_args()

    try:
        import MDAnalysis  # noqa: F401
        frames = frames_mdanalysis(a.topology, a.trajectory, a.frames)
        reader = "MDAnalysis"
    except ImportError:
        frames = frames_sphereshade(a.trajectory, a.frames)
        reader = "sphereshade (MDAnalysis is not installed)"
    print(f"reading frames with {reader}", file=sys.stderr)

    scene = sphereshade.load(a.topology)  # elements, radii, colours, hierarchy
    os.makedirs(a.outdir, exist_ok=True)
    r = None
    started = time.perf_counter()
    for k, positions, t in frames:
        if r is None:
            # the camera is fitted to the first frame and kept
            r = sphereshade.Renderer(positions, scene.radii, scene.colors, scene.regions,
                                     width=a.width, height=a.height)
        else:
            r.set_positions(positions)
        img = r.render()
        path = os.path.join(a.outdir, f"frame_{k:05d}.png")
        sphereshade.Image(img).save(path)
        print(f"frame {k} (t = {t} ps) -> {path}, {sum(r.timings.values()):.0f} ms on the GPU",
              file=sys.stderr)
    n = k + 1 if r is not None else 0
    print(f"{n} frames in {time.perf_counter() - started:.1f} s", file=sys.stderr)
    if r is not None:
        r.close()


if __name__ == "__main__":
    main()
