"""Make docs/figures/conventions.png: world frame, planes, real and virtual camera axes, grid and pixel order.

Run: ``PYTHONPATH=src python docs/figures/make_conventions.py``
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from planefuse.geometry import R_world_virtual, T_world_cam_look_at  # noqa: E402
from planefuse.grid import PlaneStack  # noqa: E402

HERE = Path(__file__).resolve().parent


def axes3(ax, origin, R, length, labels, colors=("r", "g", "b")):
    """Draw the columns of R (a frame's axes in the world) from ``origin``."""
    for k in range(3):
        d = R[:, k] * length
        ax.quiver(*origin, *d, color=colors[k], arrow_length_ratio=0.15, linewidth=2)
        ax.text(*(origin + d * 1.15), labels[k], color=colors[k], fontsize=10)


def main() -> None:
    fig = plt.figure(figsize=(17, 6.5), constrained_layout=True)
    grid = fig.add_gridspec(1, 3, width_ratios=[1.6, 1.0, 1.0])

    # (a) world, planes, real camera, virtual camera, gravity
    ax = fig.add_subplot(grid[0], projection="3d")
    X, Y = np.meshgrid(np.linspace(0, 4, 2), np.linspace(0, 4, 2))
    for h, a in ((0.0, 0.25), (1.0, 0.12)):
        ax.plot_surface(X, Y, np.full_like(X, h), alpha=a, color="tab:gray")
        ax.text(4.0, 4.0, h + 0.05, f"z = {h:g} m" + (" (pi_ref)" if h == 0 else ""), fontsize=9)
    axes3(ax, np.zeros(3), np.eye(3), 1.0, ("X_W", "Y_W", "Z_W (up)"))
    c = np.array([1.0, 3.5, 2.6])
    T = T_world_cam_look_at(c, [3.0, 1.0, 0.0])
    axes3(ax, c, T[:3, :3], 0.7, ("x_cam", "y_cam", "z_cam"))
    axes3(ax, c, np.asarray(R_world_virtual), 1.2, ("x'", "y'", "z'"), colors=("salmon", "lightgreen", "lightblue"))
    ax.text2D(0.0, 0.02, "camera {C}: x right, y down, z = optical axis (T_world_cam: {C} -> {W})\n"
              "virtual camera {V}, same centre: x' = X, y' = -Y, z' = -Z along gravity",
              transform=ax.transAxes, fontsize=9)
    ax.quiver(3.5, 3.5, 2.5, 0, 0, -0.8, color="k", arrow_length_ratio=0.2)
    ax.text(3.55, 3.5, 2.0, "gravity g", fontsize=9)
    ax.set_xlim(0, 4)
    ax.set_ylim(0, 4)
    ax.set_zlim(0, 3)
    ax.set_xlabel("X [m]")
    ax.set_ylabel("Y [m]")
    ax.set_zlabel("Z [m]")
    ax.set_title("(a) world {W}: right-handed, Z up against gravity, metres")
    ax.view_init(elev=22, azim=-60)

    # (b) plane grid index order
    ax = fig.add_subplot(grid[1])
    stack = PlaneStack(heights_m=(0.0,), x_min_m=0.0, y_min_m=0.0, cell_size_m=1.0, nx=4, ny=3)
    idx = np.arange(stack.ny * stack.nx).reshape(stack.ny, stack.nx)
    ax.imshow(idx, origin="lower", extent=stack.extent_m, cmap="Pastel1")
    for iy in range(stack.ny):
        for ix in range(stack.nx):
            x, y = stack.xy_from_index(iy, ix)
            ax.text(x, y, f"[l, {iy}, {ix}]", ha="center", va="center", fontsize=9)
    ax.set_xlabel("world X [m]  ->  column ix")
    ax.set_ylabel("world Y [m]  ->  row iy")
    ax.set_title("(b) plane stack arrays (L, ny, nx):\nrow iy grows with Y, column ix with X (imshow origin='lower')")

    # (c) pixels
    ax = fig.add_subplot(grid[2])
    w, h = 6, 4
    ax.imshow(np.add.outer(np.arange(h), np.arange(w)) % 2, cmap="Greys", alpha=0.25,
              extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    ax.plot(0, 0, "ro")
    ax.text(0.1, 0.3, "(u, v) = (0, 0):\ncentre of the top-left pixel", color="r", fontsize=9)
    ax.annotate("", (3.5, -0.3), (0, -0.3), arrowprops=dict(arrowstyle="->", color="r"))
    ax.text(3.6, -0.25, "u (right)", color="r")
    ax.annotate("", (-0.3, 3.0), (-0.3, 0), arrowprops=dict(arrowstyle="->", color="g"))
    ax.text(-0.45, 3.3, "v (down)", color="g")
    ax.set_xlim(-0.8, w - 0.5)
    ax.set_ylim(h - 0.5, -0.8)
    ax.set_title("(c) pixels: image[v, u]; H_plane_image maps\npixels (u, v) to plane XY [m]")
    ax.set_xticks(range(w))
    ax.set_yticks(range(h))

    out = HERE / "conventions.png"
    fig.savefig(out, dpi=80)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
