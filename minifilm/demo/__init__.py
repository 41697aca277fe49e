"""Steer it live: the paper's real-time stylised controller (Sec. 4.4) as a demo in the browser.

    minifilm demo --params ../shared/data/released-lpn      # the authors' released network
    minifilm demo --run runs/train_small                    # a run folder of minifilm train
    python -m minifilm.demo ...                             # the same

A local server (127.0.0.1 unless told otherwise) serves a page that draws the character with
the motion player's three.js code and sends what the user holds (WASD / arrows, Q/E, Shift, a
gamepad), the style picked or blended, and the toggles; the character's state lives on the
server, which steps the runtime Controller at the data's frame rate and streams every frame back.

Files, from the page inwards: ``assets/`` (the page: demo.html, demo.js, demo.css), ``page_files.py``
(the files the server may send), ``server.py`` (HTTP + one WebSocket per page, the
``websockets`` package of the ``demo`` extra), ``protocol.py`` (every message both ways, and the
validation of the page's), ``frame_loop.py`` (the frame loop on its own thread), ``character.py``
(one page's character: Controller, guard against non-finite output), ``steering.py`` (keys and
sticks to a target facing and velocity), ``style_mix.py`` (smooth style changes and blends),
``calibrations.py`` (speed calibration per style, measured in the frame loop's idle
time), ``source.py`` (released network or run folder), ``record.py`` (a scripted session
recorded server-side, for a GIF), ``client.py`` (a page without a browser: tests, benchmarks),
``process.py`` (the command in a process of its own, for the same).
Importing this package loads none of them.
"""
