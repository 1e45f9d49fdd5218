"""wovenskin: gesture control of a robot arm through a woven capacitive tactile skin.

Subpackages, one per stage of the pipeline, bottom layer first (docs/architecture.md; a
package imports only from lower layers):

- :mod:`wovenskin.ros2` -- ROS 2 without a ROS install: message types, DDS participant;
- :mod:`wovenskin.skin` -- skin layout, frames, wire protocol, the serial source;
- :mod:`wovenskin.recording` -- the native recording format, interchange formats, bags, replay;
- :mod:`wovenskin.signal` -- calibration, baseline tracking, filtering, contacts, lift-off;
- :mod:`wovenskin.tracking` -- fingertips followed from landing to lift, the touch so far;
- :mod:`wovenskin.sim` -- the physically motivated simulated skin and simulated people;
- :mod:`wovenskin.independent` -- a second stream generator made apart from ``sim``;
- :mod:`wovenskin.recognition` -- the live recogniser (ONNX Runtime) and the execution rules;
- :mod:`wovenskin.robots` -- the robot interface and one folder per arm (sim, techman, ur, ros2);
- :mod:`wovenskin.tasks` -- the user study's scenes on the simulated arm;
- :mod:`wovenskin.control` -- action mapping, motion shaping, the safety layer, the session;
- :mod:`wovenskin.training` -- data sets, models, training and adapting (PyTorch);
- :mod:`wovenskin.teleop` -- keyboard and teach pendant, the interfaces beside the skin;
- :mod:`wovenskin.runtime` -- the composition root: sessions opened from specs;
- :mod:`wovenskin.operators` -- simulated operators with human timing;
- :mod:`wovenskin.study` -- user studies: plans, trials, questionnaires, reports;
- :mod:`wovenskin.ui` -- terminal views, guided recording, the web dashboard;
- :mod:`wovenskin.bench` -- benchmarks behind ``wovenskin bench``;
- :mod:`wovenskin.reproduce` -- the paper's evaluation regenerated;
- :mod:`wovenskin.cli` -- the ``wovenskin`` command.

The top-level modules (errors, io, settings, specs, outputs, wording, gestures,
custom_gestures) are the foundation every package may use.
"""

__version__ = "0.1.0"
