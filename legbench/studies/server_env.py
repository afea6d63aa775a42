"""Imported first by legbench's fork server (:func:`legbench.studies.executors._start_server`).

The server is started with ``PYTHONSAFEPATH`` and ``PYTHONPATH`` set for its own import path; this module puts
the environment back as the parent had it (the values travel in ``LEGBENCH_FORKSERVER_ENV``, JSON), before the
server imports anything else, so that no process it forks, legbench's workers or another library's, inherits them.
"""

from __future__ import annotations

import json
import os

_saved = os.environ.pop("LEGBENCH_FORKSERVER_ENV", None)
if _saved is not None:
    for _name, _value in json.loads(_saved).items():
        if _value is None:
            os.environ.pop(_name, None)
        else:
            os.environ[_name] = _value
