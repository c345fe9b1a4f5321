"""An offline run's samples → a bag in the recorder's format, and the run record it carries
(the scene and its effective parameters: enough to run it again)."""
import os
from typing import TYPE_CHECKING

from .engine.samples import SampleBlock
from .scene import SceneError, SceneFile, content_sha256
from .sensors.specs import SensorSettings

if TYPE_CHECKING:
    from .offline import RunResult


class BagSink:
    """Samples → the recorder's bag format: same topics, types, frames and stamps as live."""

    def __init__(self, scene: SceneFile, directory: str, extra: dict, parameters=None):
        from .bag.writer import BagWriter
        from .engine import EngineConfig
        from .engine.actuators import ActuatorConfig
        from .param_spec import coerce_all
        from .engine.specs import SIMULATOR
        from .nodes.state_messages import StateMessages
        p = scene.simulator
        self.msgs = StateMessages(p['frame_id'], p['child_frame_id'], torque=scene.controlled,
                                  actuators=ActuatorConfig.from_parameters(
                                      coerce_all(SIMULATOR, p)))
        self.writer = BagWriter(directory, name=os.path.basename(os.path.normpath(directory)))
        self.path = os.path.abspath(directory)
        for topic, type_name in self.msgs.topic_types():
            self.writer.add_topic(f'/{topic}', type_name)
        self.sensors = None  # the scene's gyro / star tracker topics, if it has sensors
        settings = SensorSettings.from_parameters(p)
        if settings is not None:
            from .nodes.sensor_messages import SensorMessages
            self.sensors = SensorMessages(settings, p['frame_id'], p['child_frame_id'])
            for topic, type_name in self.sensors.topic_types():
                self.writer.add_topic(f'/{topic}', type_name)
        self.orbit = None  # the orbit's topics, for a scene with an orbit (as live)
        config = EngineConfig.from_parameters(p)
        if config.environment is not None:
            from .nodes.orbit_messages import OrbitMessages
            self.orbit = OrbitMessages(config, p['frame_id'], p['child_frame_id'],
                                       p['orbit.frame_id'])
            for topic, name in self.orbit.topic_types():
                self.writer.add_topic(f'/{topic}', name)
        self.magnetometer = None  # magnetic_field, for a scene with a magnetometer
        magnetic = None if config.environment is None else config.environment.magnetic
        if magnetic is not None and magnetic.magnetometer is not None:
            from .nodes import magnetic_messages
            self.magnetometer = magnetic_messages.MagnetometerMessages(
                magnetic.magnetometer, p['child_frame_id'])
            self.writer.add_topic(f'/{magnetic_messages.TOPIC}', magnetic_messages.TYPE)
        self.msgs.prepare()  # the encoder's templates now, not in the first sample's time
        self.record = run_record(scene, parameters or scene.simulator, extra)
        self.writer.add_run_configuration(self.record)

    def finish(self, result: 'RunResult'):
        """Complete the run record with what ran (readers use the last record)."""
        self.record.update(ran(result))
        self.writer.add_run_configuration(self.record)

    def __call__(self, block: SampleBlock):
        write = self.writer.write
        sensed = self.sensors is not None and block.sensors is not None
        magnetic = self.magnetometer is not None and block.magnetometer is not None
        if sensed or magnetic:  # readings at their own instants, merged in time order
            records = [(int(block.t_ns[i]), topic, data) for i in range(len(block))
                       for topic, data in self.msgs.serialized(block, i, int(block.t_ns[i]))]
            if sensed:
                records += self.sensors.serialized(block.sensors)
            if magnetic:
                records += self.magnetometer.serialized(block.magnetometer)
            if self.orbit is not None:
                records += [(int(block.t_ns[i]), topic, data) for i in range(len(block))
                            for topic, data in self.orbit.serialized(block, i,
                                                                     int(block.t_ns[i]))]
            for ns, topic, data in sorted(records, key=lambda r: r[0]):  # stable: time order
                write(f'/{topic}', data, ns, ns)
            return
        for i in range(len(block)):
            ns = int(block.t_ns[i])
            for topic, data in self.msgs.serialized(block, i, ns):
                write(f'/{topic}', data, ns, ns)
            if self.orbit is not None:
                for topic, data in self.orbit.serialized(block, i, ns):
                    write(f'/{topic}', data, ns, ns)

    def close(self):
        self.writer.close()


def run_record(scene: SceneFile, parameters: dict, extra: dict) -> dict:
    """The run configuration stored in the bag: the scene (name, file, content hash) and
    the effective parameters, enough to run it again (:func:`scene_from_record`)."""
    try:
        digest = content_sha256([scene.path])
    except OSError:
        digest = None  # an inline scene (tests, campaigns): no file
    return {'scene': scene.name, 'scene_file': os.path.abspath(scene.path),
            'scene_sha256': digest, 'mode': 'offline',
            'simulator_parameters': parameters, 'controller_parameters': scene.controller,
            **extra}


def ran(result: 'RunResult') -> dict:
    """What actually ran: the method, its step and auto's reason (or the scene's)."""
    return {'integrator': result.integrator, 'step': result.step, 'reason': result.reason,
            'steps': result.steps, 'duration': result.duration, 'samples': result.sample_count}


def scene_from_record(config: dict) -> SceneFile:
    """The scene a bag's run record describes, to run it again (its parameters as they
    ran, CLI overrides included); SceneError if the record lacks them."""
    from .engine import specs
    from .param_spec import coerce_all
    sim = config.get('simulator_parameters')
    if not isinstance(sim, dict):
        raise SceneError('the run record has no simulator_parameters (not an offline run\'s '
                         'bag?)')
    ctl = config.get('controller_parameters') or {}
    try:
        sim = coerce_all(specs.SIMULATOR, sim)
        ctl = coerce_all(specs.CONTROLLER, ctl) if ctl else {}
    except ValueError as exc:
        raise SceneError(f'run record: {exc}') from None
    return SceneFile(str(config.get('scene') or 'recorded'), '',
                     config.get('scene_file') or 'recorded', sim, ctl)
