"""The live web dashboard (``wovenskin run``): skin heatmap, recognition, 3D arm, controls.

:mod:`.scene` turns a MuJoCo arm model and joint angles into what the page's three.js view
draws; :mod:`.snapshot` turns a running control session into one JSON-ready frame of the
page; :mod:`.runner` runs the session on its own thread at the skin's full rate and takes
the page's commands and virtual touches; :mod:`.server` is the FastAPI app (page, static
files, one WebSocket per browser, token check) and :func:`.server.serve` runs it.
"""
