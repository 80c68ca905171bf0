"""MAVLink's degE7 unit (latitude and longitude as int32 degrees x 1e7, common.xml), without pymavlink.

The MAVLink adapters (:mod:`acquisition.mavlink_items`, :mod:`acquisition.mavlink_messages`)
convert with these constants, and so do the readers of logs in the same unit (PX4's uORB
topics exported as CSV by ``ulog2csv``). They live here, apart from the adapters, because the
adapters import pymavlink's dialect (about 0.1 s), which reading a CSV or GPX track must not pay.
"""

from __future__ import annotations

#: degE7 units in one degree.
E7_PER_DEG = 10_000_000

#: One degE7 unit in degrees.
DEG_PER_E7 = 1 / E7_PER_DEG
