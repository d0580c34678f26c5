"""sphereshade from Python: numpy arrays in, images out.

The same library as the `sphereshade` command line (DESIGN.md "Python"):

    import numpy as np, sphereshade
    img = sphereshade.render(positions, radii, width=800, height=600, shadows="issm-soft")
    sphereshade.Image(img)            # displays inline in Jupyter
    sphereshade.Image(img).save("out.png")

    r = sphereshade.Renderer(positions, radii, width=800, height=600, issm_t=1)
    for frame in trajectory:          # e.g. MDAnalysis: u.trajectory
        r.set_positions(frame)        # uploads positions only
        img = r.render()              # releases the GIL while the GPU works
    print(r.timings)                  # ms per pass of the last frame

Options take the CLI names with `_` for `-` (`issm_t=1`, `view_dir=(0, 0, -1)`,
`aov="id"`, `validate=True`); a bad value raises ValueError with the CLI's
message.
"""

from ._sphereshade import Renderer, Scene, Trajectory, encode_png, image_sha256, load

__all__ = [
    "Image", "Renderer", "Scene", "Trajectory", "encode_png", "image_sha256", "load", "render",
]


def render(positions, radii, colors=None, regions=None, *, width=1920, height=1080,
           shadows="issm-soft", ssdo="semantic", camera=None, **options):
    """Renders spheres once: (H, W, 4) uint8 for aov="color" (default) and
    "id", (H, W) for "depth" (uint16), "shadow" and "ao" (uint8).

    positions (N, 3) and radii (N,) are float32/float64; colors (N, 4) uint8
    RGBA and regions (N, L) uint32 (L <= 4 hierarchy levels, outermost
    first) are optional (without colours the spheres are coloured as an
    .xyzr file with the same columns). camera: a dict of view_dir, up,
    view_center, view_height, fov.
    """
    r = Renderer(positions, radii, colors, regions, width=width, height=height,
                 shadows=shadows, ssdo=ssdo, camera=camera, **options)
    try:
        return r.render()
    finally:
        r.close()


class Image:
    """An image array that displays itself in Jupyter (PNG) and saves the
    PNG bytes the command line would write."""

    def __init__(self, array):
        self.array = array

    def png(self):
        return encode_png(self.array)

    def _repr_png_(self):
        return self.png()

    def save(self, path):
        with open(path, "wb") as f:
            f.write(self.png())

    def __array__(self, dtype=None, copy=None):
        import numpy as np
        return np.asarray(self.array, dtype=dtype)

    def __repr__(self):
        return f"sphereshade.Image({self.array.shape}, {self.array.dtype})"
