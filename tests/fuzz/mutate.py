"""Ways to break an .npz archive, shared by the fuzz tests: at the byte level (truncated, flipped,
padded) and at the array level (NaN, other dtypes and shapes, missing or extra arrays, forged
headers)."""
import io
import json
import zipfile

import numpy as np


def byte_mutations(rng, n_cut=10, n_flip=10):
    """(name, bytes -> bytes)"""
    out = [("empty", lambda b: b""), ("text", lambda b: b"hello, not an archive\n"),
           ("random bytes", lambda b: np.random.default_rng(1).bytes(2048)),
           ("garbage appended", lambda b: b + np.random.default_rng(2).bytes(100)),
           ("zip of a text file", lambda b: _zip({"note.txt": b"hi"}))]
    for k in range(n_cut):
        out.append((f"cut #{k}", lambda b, s=int(rng.integers(1 << 30)): b[:np.random.default_rng(s).integers(1, len(b))]))
    for k in range(n_flip):
        def flip(b, s=int(rng.integers(1 << 30))):
            r = np.random.default_rng(s)
            a = bytearray(b)
            for i in r.integers(0, len(a), size=3):
                a[i] ^= int(r.integers(1, 256))
            return bytes(a)
        out.append((f"flipped #{k}", flip))
    out.append(("zeroed block", lambda b: b[:len(b) // 2] + bytes(64) + b[len(b) // 2 + 64:]))
    return out


def _zip(members: dict) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    return buf.getvalue()


def npy_bytes(array) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.asarray(array), allow_pickle=True)
    return buf.getvalue()


def forged_header(shape, dtype="<f8", data=b"\0" * 64) -> bytes:
    """An .npy member whose header declares ``shape`` but holds only ``data``."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": dtype, "fortran_order": False, "shape": tuple(shape)})
    return buf.getvalue() + data


def read_members(path) -> dict:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def write_members(path, arrays: dict, raw: dict = None) -> None:
    """An .npz of ``arrays`` plus ``raw`` name -> .npy bytes members (for forged ones)."""
    members = {f"{k}.npy": npy_bytes(v) for k, v in arrays.items()}
    members.update({f"{k}.npy": v for k, v in (raw or {}).items()})
    with open(path, "wb") as f:
        f.write(_zip(members))


def array_mutations(arrays: dict, rng, float_names, n_each=2):
    """(name, arrays -> (arrays, raw members)) edits of the arrays of an archive."""
    names = sorted(float_names)
    pick = lambda: names[rng.integers(len(names))]
    out = []

    def with_value(name, value, pos):
        def edit(a):
            a = dict(a)
            v = np.array(a[name], copy=True)
            v.reshape(-1)[pos % max(1, v.size)] = value
            a[name] = v
            return a, {}
        return edit

    for value in (np.nan, np.inf, -np.inf):
        for _ in range(n_each):
            name = pick()
            out.append((f"{value} in {name}", with_value(name, value, int(rng.integers(1 << 20)))))
    for dtype in ("int64", "bool", "complex128", "U3"):
        name = pick()
        out.append((f"{name} as {dtype}", lambda a, n=name, d=dtype: ({**a, n: np.asarray(a[n]).astype(d)}, {})))
    for _ in range(n_each):
        name = pick()
        out.append((f"{name} missing", lambda a, n=name: ({k: v for k, v in a.items() if k != n}, {})))
        out.append((f"{name} with an extra axis", lambda a, n=name: ({**a, n: np.asarray(a[n])[None]}, {})))
        out.append((f"{name} emptied", lambda a, n=name: ({**a, n: np.asarray(a[n]).reshape(-1)[:0]}, {})))
        out.append((f"{name} one row short", lambda a, n=name: ({**a, n: np.asarray(a[n])[:-1]}, {})))
    name = pick()
    out.append((f"{name} as Python objects", lambda a, n=name: ({k: v for k, v in a.items() if k != n},
                                                              {n: npy_bytes(np.array([{"x": 1}], dtype=object))})))
    out.append((f"{name} forged to 10^12 floats", lambda a, n=name: ({k: v for k, v in a.items() if k != n},
                                                                   {n: forged_header((10**12,))})))
    out.append((f"{name} forged to 2^40 x 2^40", lambda a, n=name: ({k: v for k, v in a.items() if k != n},
                                                                   {n: forged_header((2**40, 2**40))})))
    out.append(("an extra unknown array", lambda a: ({**a, "zzz_unknown": np.zeros(3)}, {})))
    return out


def json_member(arrays: dict, key: str, edit) -> dict:
    """``arrays`` with the JSON string array ``key`` edited by ``edit(dict) -> dict | str``."""
    meta = json.loads(str(arrays[key]))
    new = edit(meta)
    return {**arrays, key: np.array(new if isinstance(new, str) else json.dumps(new))}
