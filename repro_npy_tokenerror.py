# .npy with a corrupt header dict (unbalanced bracket): load_volume raises tokenize.TokenError, not InputError;
# `parc info bad.npy` prints a traceback and exits 1.
import subprocess, sys
hdr = b"{'descr': '<f4', 'fortran_order': False, 'shape': (3, 4, 5, }"
hdr = hdr + b" " * (117 - len(hdr)) + b"\n"            # header padded to a multiple of 64 with the 10-byte preamble
open("/tmp/hunt_io/bad_header.npy", "wb").write(b"\x93NUMPY\x01\x00" + len(hdr).to_bytes(2, "little") + hdr + b"\0" * 240)
try:
    from data_tools.io import load_volume
    load_volume("/tmp/hunt_io/bad_header.npy")
except Exception as e:
    print("load_volume raised", type(e).__module__, type(e).__name__, e)
r = subprocess.run(["parc", "info", "/tmp/hunt_io/bad_header.npy"], capture_output=True, text=True)
print("exit", r.returncode, "| traceback in stderr:", "Traceback" in r.stderr, "|", r.stderr.strip().splitlines()[-1])
