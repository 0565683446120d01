"""Write small ArduPilot DataFlash (.bin) logs for the format tests (no real log is vendored:
the ArduPilot sets in shared/data/real carry no licence)."""

from __future__ import annotations

import struct
from pathlib import Path

HEAD = b"\xa3\x95"
FMT_ID = 0x80
# struct of each DataFlash format character (DFReader FORMAT_TO_STRUCT, multipliers aside)
_S = {"Q": "Q", "I": "I", "B": "B", "f": "f", "h": "h", "H": "H", "i": "i", "L": "i",
      "e": "i", "c": "h", "C": "H", "Z": "64s", "N": "16s", "n": "4s", "d": "d"}
_MULT = {"L": 1e7, "e": 100.0, "c": 100.0, "C": 100.0}


class DataFlashWriter:
    """Define message formats, then append records (values in the log's units)."""

    def __init__(self) -> None:
        self.buf = bytearray()
        self.fmts: dict[str, tuple[int, str, list[str]]] = {}
        self._fmt("FMT", FMT_ID, "BBnNZ", "Type,Length,Name,Format,Columns")

    def _fmt(self, name: str, type_id: int, fmt: str, cols: str) -> None:
        length = 3 + struct.calcsize("<" + "".join(_S[c] for c in fmt))
        self.fmts[name] = (type_id, fmt, cols.split(","))
        body = struct.pack("<BB4s16s64s", type_id, length, name.encode(), fmt.encode(),
                           cols.encode())
        self.buf += HEAD + bytes([FMT_ID]) + body

    def define(self, name: str, fmt: str, cols: str) -> None:
        self._fmt(name, 0x81 + len(self.fmts), fmt, cols)

    def add(self, name: str, **values: float | str) -> None:
        type_id, fmt, cols = self.fmts[name]
        packed = []
        for c, col in zip(fmt, cols, strict=True):
            v = values.get(col, 0)
            if c in ("Z", "N", "n"):
                packed.append(str(v).encode())
            elif c in _MULT:
                packed.append(int(round(float(v) * _MULT[c])))
            elif c in "fd":
                packed.append(float(v))
            else:
                packed.append(int(v))
        self.buf += HEAD + bytes([type_id]) + struct.pack(
            "<" + "".join(_S[c] for c in fmt), *packed)

    def write(self, path: Path) -> Path:
        Path(path).write_bytes(bytes(self.buf))
        return Path(path)


def plane_log(path: Path, *, seconds: float = 20.0, imu_hz: float = 200.0) -> Path:
    """A level ArduPlane flight at 20 m/s north-east: current names (TimeUS, instance I),
    two IMUs, two airspeed sensors, AOA, BARO, GPS at 5 Hz, RCOU, CTUN, NTUN."""
    w = DataFlashWriter()
    w.define("MSG", "QZ", "TimeUS,Message")
    w.define("IMU", "QBffffff", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ")
    w.define("ATT", "QccccCC", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw")
    w.define("GPS", "QBBIHBLLeffff", "TimeUS,I,Status,GMS,GWk,NSats,Lat,Lng,Alt,Spd,GCrs,VZ,Yaw")
    w.define("ARSP", "QBfff", "TimeUS,I,Airspeed,DiffPress,Temp")
    w.define("AOA", "Qff", "TimeUS,AOA,SSA")
    w.define("BARO", "QBffcf", "TimeUS,I,Alt,Press,Temp,CRt")
    w.define("RCOU", "QHHHH", "TimeUS,C1,C2,C3,C4")
    w.define("CTUN", "Qccf", "TimeUS,NavRoll,NavPitch,Aspd")
    w.define("NTUN", "Qfff", "TimeUS,Dist,TBrg,NavBrg")
    w.add("MSG", TimeUS=1000, Message="ArduPlane V4.5.0 (test)")
    t0 = 10_000_000
    n = int(seconds * imu_hz)
    for k in range(n):
        t = t0 + int(k * 1e6 / imu_hz)
        for i in (0, 1):
            w.add("IMU", TimeUS=t, I=i, GyrX=0.01, GyrY=-0.02, GyrZ=0.03, AccX=0.5,
                  AccY=-0.2, AccZ=-9.8)
        if k % int(imu_hz / 50) == 0:
            w.add("ATT", TimeUS=t, DesRoll=1.0, Roll=2.0, DesPitch=3.0, Pitch=4.0, DesYaw=44.0,
                  Yaw=45.0)
        if k % int(imu_hz / 20) == 0:
            for i in (0, 1):
                w.add("ARSP", TimeUS=t, I=i, Airspeed=21.0 + i, DiffPress=270.0, Temp=15.0)
            w.add("AOA", TimeUS=t, AOA=3.0, SSA=-1.0)
            w.add("BARO", TimeUS=t, I=0, Alt=100.0, Press=100_129.0, Temp=14.0, CRt=0.5)
        if k % int(imu_hz / 10) == 0:
            w.add("RCOU", TimeUS=t, C1=1500, C2=1600, C3=1400, C4=1100)
            w.add("CTUN", TimeUS=t, NavRoll=5.0, NavPitch=2.0, Aspd=21.5)
            w.add("NTUN", TimeUS=t, Dist=300.0, TBrg=90.0, NavBrg=80.0)
        if k % int(imu_hz / 5) == 0:
            w.add("GPS", TimeUS=t, I=0, Status=3, GMS=0, GWk=0, NSats=12, Lat=47.3,
                  Lng=8.5, Alt=500.0, Spd=20.0, GCrs=45.0, VZ=-0.5, Yaw=0.0)
    return w.write(path)
