"""Classical baselines, one module per family: PD/PID and a plant's own lab PD (pid.py), Southward and
RDFC (southward_rdfc.py), state feedback + observer with relay / high-gain compensation
(state_feedback.py), LuGre-observer compensation (lugre_observer.py) and Coulomb + viscous feed-forward
on the PD or the PID loop (feedforward.py); and, not baselines, residual bases scheduled over them by the
reference's speed or by the task (scheduled.py). Each family's settings object reads its defaults from
configs/controllers.yaml once; constructor arguments override."""

from .adaptive import AdaptiveCoulomb, AdaptiveSettings
from .disturbance_observer import DisturbanceObserver, ModelFFDisturbanceObserver, ObserverSettings
from .feedforward import CoulombViscousFF, PIDCoulombViscousFF
from .iterative import IterativeLearning, LearningSettings
from .lugre_observer import LuGreObserver, LuGreObserverSettings
from .model_feedforward import CascadeModelFF, CascadeSettings, FeedForwardSettings, PIDModelFF
from .pid import PD, PID, LabPD, PIDSettings, design_pid
from .scheduled import (
    SpeedScheduled,
    SpeedScheduledSettings,
    TaskScheduled,
    TaskScheduledSettings,
)
from .southward_rdfc import RDFC, RDFCSettings, Southward, SouthwardSettings
from .state_feedback import ResidualBaseSettings, StateFeedback, StateFeedbackSettings

__all__ = [
    "PD",
    "PID",
    "RDFC",
    "AdaptiveCoulomb",
    "AdaptiveSettings",
    "CascadeModelFF",
    "CascadeSettings",
    "CoulombViscousFF",
    "DisturbanceObserver",
    "FeedForwardSettings",
    "IterativeLearning",
    "LabPD",
    "LearningSettings",
    "LuGreObserver",
    "LuGreObserverSettings",
    "ModelFFDisturbanceObserver",
    "ObserverSettings",
    "PIDCoulombViscousFF",
    "PIDModelFF",
    "PIDSettings",
    "RDFCSettings",
    "ResidualBaseSettings",
    "Southward",
    "SouthwardSettings",
    "SpeedScheduled",
    "SpeedScheduledSettings",
    "StateFeedback",
    "StateFeedbackSettings",
    "TaskScheduled",
    "TaskScheduledSettings",
    "design_pid",
]
