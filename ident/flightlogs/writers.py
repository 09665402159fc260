"""Writers of the autopilots' log formats, so that the project's own flights (the twin, a simulated loop) can be
read back through the readers: ULog through pyulog's writer, DataFlash with pymavlink's format definitions.

Both take topics/messages by name, the names of :mod:`~rotorlab.ident.flightlogs.names`.
"""

from __future__ import annotations

import io
import struct
from pathlib import Path

import numpy as np

from rotorlab.atomic import atomic_path

__all__ = ["write_ulog", "write_dataflash", "ulog_field_type"]

# ULog header: magic, version 1, start timestamp; then the mandatory flag-bits message (no flags set)
_ULOG_HEADER = b"ULog\x01\x12\x35\x01" + struct.pack("<Q", 0)
_ULOG_FLAGS = struct.pack("<HB", 40, ord("B")) + bytes(40)


def ulog_field_type(values) -> str:
    """The ULog C type a numpy array is written as (``uint64_t`` for time stamps, ``uint8_t`` for small
    unsigned integers such as states, else ``float``)."""
    a = np.asarray(values)
    if a.dtype == np.uint64:
        return "uint64_t"
    if a.dtype == np.uint8 or a.dtype == np.bool_:
        return "uint8_t"
    if np.issubdtype(a.dtype, np.integer):
        return "int32_t"
    return "float"


def write_ulog(path, topics: dict, params: dict | None = None, info: dict | None = None) -> Path:
    """Write a ULog file with pyulog's writer (``ULog.write_ulog``, pyulog >= 1.3).

    pyulog writes back logs it has read and has no constructor for a new one, so an empty log (header and
    flag bits only) is parsed and its format, subscription and data tables filled the way pyulog's own parser
    fills them; the bytes are then pyulog's.

    Parameters
    ----------
    path : str or Path
    topics : dict
        ``{topic: {field: array}}``, each with a ``timestamp`` field in microseconds (written as uint64); array
        fields named like ``xyz[0]``, ``q[3]`` are written as C arrays the way uORB logs them. Instance 0.
    params : dict, optional
        ``{name: value}``; ints are written as int32, floats as float.
    info : dict, optional
        ``{key: str}`` info messages (``sys_name``, ``ver_sw``; ``ver_sw_release`` may be an int).

    Examples
    --------
    >>> write_ulog("flight.ulg", {"vehicle_rates_setpoint": {"timestamp": t_us, "roll": p}})  # doctest: +SKIP
    """
    from pyulog import ULog

    ulog = ULog(io.BytesIO(_ULOG_HEADER + _ULOG_FLAGS))
    for msg_id, (name, fields) in enumerate(sorted(topics.items())):
        if "timestamp" not in fields:
            raise ValueError(f"topic {name} has no timestamp field")
        names = ["timestamp"] + [f for f in fields if f != "timestamp"]
        # array fields: "xyz[0]", "xyz[1]" -> one C array "float[2] xyz"
        spec, seen = [], set()
        for f in names:
            base = f.split("[")[0]
            if "[" in f:
                if base in seen:
                    continue
                seen.add(base)
                n = sum(1 for g in names if g.split("[")[0] == base and "[" in g)
                spec.append(f"{ulog_field_type(fields[f])}[{n}] {base};")
            elif f == "timestamp":
                spec.append("uint64_t timestamp;")
            else:
                spec.append(f"{ulog_field_type(fields[f])} {f};")
        fmt_bytes = f"{name}:{''.join(spec)}".encode()
        ulog._message_formats[name] = ULog.MessageFormat(fmt_bytes, None)
        add = ULog._MessageAddLogged(struct.pack("<BH", 0, msg_id) + name.encode(), None, ulog._message_formats)
        flat = np.zeros(len(fields["timestamp"]), dtype=add.dtype)
        for fd in add.field_data:
            flat[fd.field_name] = np.asarray(fields[fd.field_name])
        add.buffer = bytearray(flat.tobytes())
        ulog._data_list.append(ULog.Data(add))
    for k, v in (params or {}).items():
        ulog._initial_parameters[k] = int(v) if isinstance(v, (int, np.integer)) else float(v)
    for k, v in (info or {}).items():
        ulog._msg_info_dict[k] = v
        ulog._msg_info_dict_types[k] = "uint32_t" if isinstance(v, int) else f"char[{len(str(v))}]"
    with atomic_path(path) as tmp:
        ulog.write_ulog(str(tmp))
    return Path(path)


def write_dataflash(path, messages: dict, params: dict | None = None) -> Path:
    """Write an ArduPilot DataFlash binary log (.bin) from messages, with pymavlink's format table.

    pymavlink reads DataFlash but has no writer; its ``DFReader.FORMAT_TO_STRUCT`` and ``DFFormat`` are the
    format definitions used here, so every field is packed exactly as DFReader unpacks it. The file is the FMT
    message describing FMT, one FMT per message type, PARM messages, then the messages in time order.

    Parameters
    ----------
    path : str or Path
    messages : dict
        ``{name: (format, columns, rows)}``: DataFlash format characters (``"Qfff"``), column names, and the rows
        (sequences of values; the first column is ``TimeUS``).
    params : dict, optional
        ``{name: value}`` written as PARM messages at time 0.

    Examples
    --------
    >>> write_dataflash("flight.bin", {"RATE": ("Qfff", ["TimeUS", "RDes", "R", "ROut"], rows)})  # doctest: +SKIP
    """
    from pymavlink.DFReader import FORMAT_TO_STRUCT

    head = struct.pack("BB", 0xA3, 0x95)
    fmt_struct = "<BB4s16s64s"
    out = bytearray()

    def struct_of(fmt):
        return "<" + "".join(FORMAT_TO_STRUCT[c][0] for c in fmt)

    def mults(fmt):
        return [FORMAT_TO_STRUCT[c][1] for c in fmt]

    def fmt_msg(type_id, name, fmt, columns):
        length = 3 + struct.calcsize(struct_of(fmt))
        return head + bytes([0x80]) + struct.pack(fmt_struct, type_id, length, name.encode(), fmt.encode(),
                                                  ",".join(columns).encode())

    out += fmt_msg(0x80, "FMT", "BBnNZ", ["Type", "Length", "Name", "Format", "Columns"])
    all_msgs = dict(messages)
    if params:
        all_msgs["PARM"] = ("QNf", ["TimeUS", "Name", "Value"], [(0, k, float(v)) for k, v in params.items()])
    types = {}
    for i, (name, (fmt, columns, _rows)) in enumerate(all_msgs.items()):
        types[name] = 10 + i
        out += fmt_msg(types[name], name, fmt, columns)
    timed = []
    for name, (fmt, _columns, rows) in all_msgs.items():
        st, mu = struct_of(fmt), mults(fmt)
        for row in rows:
            vals = []
            for v, c, m in zip(row, fmt, mu):
                if isinstance(v, str):
                    v = v.encode()
                elif m is not None:
                    v = int(round(v / m))
                elif FORMAT_TO_STRUCT[c][2] is int:
                    v = int(v)
                vals.append(v)
            timed.append((int(row[0]), head + bytes([types[name]]) + struct.pack(st, *vals)))
    timed.sort(key=lambda x: x[0])
    out += b"".join(b for _, b in timed)
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(bytes(out))
    return Path(path)
