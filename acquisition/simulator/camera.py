"""The simulated camera's memory card: one small JPEG per photo, stamped by a camera clock.

A real survey camera writes each frame with the time of its own clock, which is off from UTC by
an unknown offset (set by hand, drifting, in local time); the autopilot logs its camera events
in UTC. ``sfap geotag`` has to find that offset by aligning the two. :class:`FrameCard` makes
such a card for the simulated vehicle so that the whole chain can be tried with no hardware:

- a frame per photo the vehicle takes, named ``IMG_0001.JPG``, ``IMG_0002.JPG``... in the
  order they are written, a small real JPEG (64 x 48 px, Pillow) whose pixels are a pattern
  of the photo number, so that no two frames are byte-identical;
- EXIF DateTimeOriginal and SubSecTimeOriginal (milliseconds) give the photo's time on the
  camera clock: the true UTC time of the photo plus ``clock_offset_s``, written as a wall
  time with no zone, as most cameras write it; Make "sfap" and Model "simulated camera" say
  what it is (no database camera matches them: ``sfap check`` then takes the plan's camera);
- ``drop``: photo numbers (1 = the first photo) the camera misses (an event with no frame,
  as when the card is slow); ``extra``: photo numbers after which the camera fires once more
  by itself ``extra_delay_s`` later (a frame with no event, as a double fire does).

EXIF is written with pyexiv2 (the library acquisition/exif.py uses); the frames are written
atomically (temporary name, then rename), so a reader never sees half a file.
"""

from __future__ import annotations

import io
import logging
import math
import os
from collections.abc import Collection
from datetime import UTC, datetime
from pathlib import Path

from planner.errors import InputError

log = logging.getLogger(__name__)

#: Size of the simulated frames (px). Small: the pixels carry no information.
FRAME_WIDTH_PX = 64
FRAME_HEIGHT_PX = 48


def _jpeg_bytes(number: int) -> bytes:
    from PIL import Image

    image = Image.new("RGB", (FRAME_WIDTH_PX, FRAME_HEIGHT_PX))
    pixels = [
        ((x * 4 + number * 7) % 256, (y * 5 + number * 13) % 256, (x * y + number) % 256)
        for y in range(FRAME_HEIGHT_PX)
        for x in range(FRAME_WIDTH_PX)
    ]
    image.putdata(pixels)
    buffer = io.BytesIO()
    image.save(buffer, format="JPEG", quality=80)
    return buffer.getvalue()


def camera_clock_text(utc_s: float, clock_offset_s: float) -> tuple[str, str]:
    """(DateTimeOriginal, SubSecTimeOriginal) of a photo taken at ``utc_s`` (POSIX s) by a
    camera whose clock is ``clock_offset_s`` ahead of UTC: a zone-less wall time and its
    milliseconds."""
    camera_s = utc_s + clock_offset_s
    whole = math.floor(camera_s)
    millis = round((camera_s - whole) * 1000)
    if millis == 1000:
        whole, millis = whole + 1, 0
    moment = datetime.fromtimestamp(whole, tz=UTC)
    return moment.strftime("%Y:%m:%d %H:%M:%S"), f"{millis:03d}"


class FrameCard:
    """Writes the simulated camera's frames into ``folder`` (see the module docstring).

    ``clock_offset_s``: camera clock minus UTC (s); ``drop`` / ``extra``: photo numbers
    (from 1); ``extra_delay_s``: how long after its photo an extra frame is stamped (s).
    The folder is created; frames already in it are refused (a card from another flight
    would mix with this one).
    """

    def __init__(
        self,
        folder: str | os.PathLike[str],
        *,
        clock_offset_s: float = 0.0,
        drop: Collection[int] = (),
        extra: Collection[int] = (),
        extra_delay_s: float = 0.4,
    ) -> None:
        if not math.isfinite(clock_offset_s) or abs(clock_offset_s) > 10 * 365 * 86400:
            raise InputError(
                f"camera clock offset {clock_offset_s} s is not a usable offset (|offset| < 10 years)"
            )
        if not 0 < extra_delay_s < 60:
            raise InputError(f"extra_delay_s is {extra_delay_s}; give 0-60 s")
        for name, numbers in (("drop", drop), ("extra", extra)):
            bad = [n for n in numbers if int(n) < 1]
            if bad:
                raise InputError(f"--{name}-frame {bad[0]}: photo numbers start at 1")
        self.folder = Path(folder)
        if self.folder.exists() and not self.folder.is_dir():
            raise InputError(f"{self.folder} exists and is not a folder; choose another --frames folder")
        if self.folder.is_dir() and any(self.folder.glob("*.JPG")):
            raise InputError(
                f"{self.folder} already holds frames (*.JPG); give an empty or new --frames folder "
                f"so that two flights do not mix"
            )
        self.folder.mkdir(parents=True, exist_ok=True)
        self.clock_offset_s = float(clock_offset_s)
        self.drop = frozenset(int(n) for n in drop)
        self.extra = frozenset(int(n) for n in extra)
        self.extra_delay_s = extra_delay_s
        self.photos = 0  # photos the vehicle took
        self.frames = 0  # frames written
        #: (file name, photo number or None for an extra frame, UTC of the exposure) per frame.
        self.written: list[tuple[str, int | None, float]] = []

    def photo(self, utc_s: float) -> None:
        """The vehicle took a photo at ``utc_s`` (POSIX s, UTC): write its frame(s)."""
        self.photos += 1
        number = self.photos
        if number in self.drop:
            log.info("simulated camera: photo %d dropped (no frame written)", number)
        else:
            self._write(number, utc_s)
        if number in self.extra:
            self._write(None, utc_s + self.extra_delay_s)

    def _write(self, number: int | None, utc_s: float) -> None:
        import pyexiv2

        self.frames += 1
        name = f"IMG_{self.frames:04d}.JPG"
        date_time, sub_sec = camera_clock_text(utc_s, self.clock_offset_s)
        image = pyexiv2.ImageData(_jpeg_bytes(self.frames))
        try:
            image.modify_exif(
                {
                    "Exif.Image.Make": "sfap",
                    "Exif.Image.Model": "simulated camera",
                    "Exif.Photo.DateTimeOriginal": date_time,
                    "Exif.Photo.SubSecTimeOriginal": sub_sec,
                }
            )
            data = image.get_bytes()
        finally:
            image.close()
        target = self.folder / name
        partial = self.folder / f".{name}.partial"
        partial.write_bytes(data)
        os.replace(partial, target)
        self.written.append((name, number, utc_s))
