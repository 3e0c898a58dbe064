"""Camera frames decoded lazily from a video file (OpenCV), with exact seeking and loud failures.

A video stream of the recording format (version 2) names a video file and, per recorded frame, its time and
the index of the video frame that holds it (every frame, or a subsample). Frames are decoded in order;
asking for an earlier frame reopens the file and decodes up to it (H.264 key-frame seeking through
``CAP_PROP_POS_FRAMES`` is not exact in every OpenCV back end, so it is not used). A frame the decoder
cannot give raises ``ValueError`` naming the camera, the frame index and its time: nothing is skipped.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

__all__ = ["VideoFrames", "video_info"]


def video_info(path: str | Path) -> tuple[int, float, int, int]:
    """``(n_frames, rate_hz, width_px, height_px)`` as the container declares them.

    Raises
    ------
    ValueError
        The file is missing or OpenCV cannot open it.
    """
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{p}: video file not found")
    cap = cv2.VideoCapture(str(p))
    try:
        if not cap.isOpened():
            raise ValueError(f"{p}: OpenCV cannot open this video (unknown container or codec)")
        return (int(cap.get(cv2.CAP_PROP_FRAME_COUNT)), float(cap.get(cv2.CAP_PROP_FPS)),
                int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    finally:
        cap.release()


class VideoFrames:
    """Decode chosen frames of a video on demand.

    Parameters
    ----------
    path : path
        The video file.
    frame_index : array_like of int, shape (F,)
        Video frame holding recorded frame ``i`` (increasing).
    times_s : array_like, shape (F,)
        Recorded frame times [s], used in error messages.
    camera : str
        Camera name, used in error messages.
    width_px, height_px : int
        Frame size the camera's calibration expects; a video of another size is refused when opened.
    """

    def __init__(self, path: str | Path, frame_index, times_s, camera: str, width_px: int, height_px: int) -> None:
        self.path = Path(path)
        self.frame_index = np.asarray(frame_index, dtype=np.int64)
        self.times_s = np.asarray(times_s, dtype=float)
        self.camera = camera
        n, _, w, h = video_info(self.path)
        if (w, h) != (width_px, height_px):
            raise ValueError(f"{self.path}: camera {camera!r} video is {w}x{h} px, its calibration {width_px}x"
                             f"{height_px} px")
        if len(self.frame_index) and np.any(np.diff(self.frame_index) <= 0):
            raise ValueError(f"{self.path}: camera {camera!r} frame indices must increase")
        if len(self.frame_index) and (self.frame_index[0] < 0 or (n > 0 and self.frame_index[-1] >= n)):
            k = int(np.searchsorted(self.frame_index, n))
            raise ValueError(f"{self.path}: camera {camera!r} video has {n} frames, shorter than its times: "
                             f"frame {k} (video frame {self.frame_index[k]}, t={float(self.times_s[k])!r} s) is past the end")
        self._cap: cv2.VideoCapture | None = None
        self._next = 0  # video frame the open capture decodes next

    def __len__(self) -> int:
        return len(self.frame_index)

    def _open(self) -> cv2.VideoCapture:
        if self._cap is not None:
            self._cap.release()
        self._cap = cv2.VideoCapture(str(self.path))
        self._next = 0
        if not self._cap.isOpened():
            raise ValueError(f"{self.path}: OpenCV cannot open this video any more (camera {self.camera!r})")
        return self._cap

    def __call__(self, i: int) -> np.ndarray:
        """Recorded frame ``i`` (H, W, 3) uint8 BGR."""
        target = int(self.frame_index[i])
        cap = self._cap
        if cap is None or target < self._next:
            cap = self._open()
        while self._next < target:  # decode forward to the frame (grab skips the colour conversion)
            if not cap.grab():
                self._fail(i, f"decoding stopped at video frame {self._next}")
            self._next += 1
        ok, img = cap.read()
        if not ok or img is None:
            self._fail(i, "the decoder returned no image")
        self._next += 1
        return img

    def _fail(self, i: int, why: str) -> None:
        self.close()
        raise ValueError(f"{self.path}: camera {self.camera!r} frame {i} (video frame {self.frame_index[i]}, "
                         f"t={float(self.times_s[i])!r} s): {why} (truncated or corrupt video?)")

    def close(self) -> None:
        """Release the decoder (reopened on the next access)."""
        if self._cap is not None:
            self._cap.release()
        self._cap = None
        self._next = 0
