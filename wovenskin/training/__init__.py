"""Training: data sets cut from simulated streams, captures and recordings; the models; the
training loops; the reports.  Needs PyTorch (``pip install -e '.[train]'``); the live path
in :mod:`wovenskin.recognition` needs neither torch nor the simulator."""
