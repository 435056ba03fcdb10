"""Ctrl-C during a long call ends it with KeyboardInterrupt and leaves the interpreter usable."""

import os
import subprocess
import sys
import textwrap


def test_ctrl_c_ends_a_long_call_early():
    script = textwrap.dedent(
        """
        import os, signal, threading, time
        import carat
        threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        start = time.monotonic()
        try:
            carat.simulate(frames=20000, laps=20, threads=2)
            print("finished")
        except KeyboardInterrupt:
            print("interrupted after %.1f s" % (time.monotonic() - start))
        s = carat.simulate(frames=4, laps=1, odometry=False, dense_graph=False)
        print("usable", len(s.frames))
        """
    )
    env = dict(os.environ)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.split("\n")
    assert lines[0].startswith("interrupted after"), out.stdout
    # 20,000 frames take many minutes; an interrupted call ends within seconds of the signal.
    assert float(lines[0].split()[2]) < 60.0
    assert lines[1] == "usable 4"
