"""`EchoDataEnv`: the dataset's world as a gymnasium environment, with live binaural audio.

One episode = one `EpisodeSpec` (floor plan, sounds, events, robot start, true skill chain).
`reset(options={"split": s, "index": i})` samples exactly the spec `echo-data build` samples for
(recipe seed, s, i) (`"attempt": k` for the build's k-th retry); `reset(seed=n)` draws a fresh
episode (the recipe under a seed drawn from n). `step(action)` applies one action for one control
period: in `action_mode="joint"` the dataset's 12-float `action`, in `action_mode="ee_delta"` its
11-float end-effector form `action.ee` (turned into joint targets by the robot's one ee map,
`robot.ee.to_joint`; docs/action_spaces.md; default: the recipe's `robot.action_space`), then:
events whose resolving skill's success test now holds stop sounding (a door found open changes
the acoustics), the robot's ears hear the control period just played (`OnlineTrack`, from the
pose the head had during it) and the cameras look. Observations carry the dataset's column
names, dtypes and shapes, plus `observation.audio.binaural`: the (hop, 2) float32 samples of that
control period (the episode WAV is these blocks one after another).

Reward: the number of true-chain skills newly completed in order at this step (their success
tests, latched); `terminated` when the whole chain is done or a non-finite action arrived (the
reason in `info["failure"]`); `truncated` past the sum of the chain's step budgets.
`info["skills"][k]["handed_over"]`: entry k's drive ends where the next skill was taught to start
(docs/handover.md; `skill_table.HandOver`) — a learned drive that does not STOP ends there. An agent that
ends its skills itself (SoundSpaces' STOP) sets `agent_stops`: the active skill then counts only
when the agent calls `stop_skill()` and its test holds there (else the episode ends failed);
`run_episode` does this for learned policies that end themselves. After either,
`step` refuses (`EnvInputError`) until `reset`, as gymnasium's API asks. Reset options and
actions are checked first: a wrong key, type or value raises `EnvInputError` naming it.

The build drives this same environment with the scripted experts (`echo_data.agents`), so a
dataset episode replays here action by action to the same states, images and audio.
"""

from __future__ import annotations

from concurrent.futures import Future
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from echo_data.dataset.schema import BINAURAL, MEL, SPECTROGRAM, STATE
from echo_data.episode import EpisodeSpec, SkillCall
from echo_data.protocols import SoundLibrary
from echo_data.recipe import Recipe
from echo_data.records import ACTION_DIM, ACTION_SPACES, EE_ACTION_DIM, STATE_DIM
from echo_data.skill_table import SKILLS, STANCE_CENTRE, Situation, apply_effect, handover_call, skill_budget
from echo_data.skills.success import in_stance

if TYPE_CHECKING:
    from echo_data.envs.audio import Heard
    from echo_data.world import World

SHIPPED_RECIPES = Path(__file__).resolve().parents[2] / "recipes"


class EnvInputError(ValueError):
    """A bad argument to the environment (index past a split, wrong action shape): one line."""


RESET_OPTIONS = ("spec", "split", "index", "attempt")


def as_action(action: Any, dim: int = ACTION_DIM) -> np.ndarray:
    """`action` as `dim` float32 (the dataset's 12-float `action`, or 11 for `action.ee`), or
    `EnvInputError` saying why it is not one (not numbers, complex numbers whose imaginary parts
    a cast would drop, the wrong shape)."""
    try:
        a = np.asarray(action)
    except Exception as e:  # ragged lists and objects numpy cannot make an array of
        raise EnvInputError(f"action: not an array of {dim} numbers ({type(e).__name__}: {e})".splitlines()[0]) from None
    if a.dtype.kind == "c":
        raise EnvInputError(f"action: complex values (dtype {a.dtype}); an action is {dim} real numbers")
    if a.dtype.kind not in "iuf":
        raise EnvInputError(f"action: expected {dim} numbers, got {type(action).__name__} of dtype {a.dtype}")
    if a.shape != (dim,):
        raise EnvInputError(f"action: expected shape ({dim},), got {a.shape}")
    return a.astype(np.float32)


def _int_option(options: dict[str, Any], key: str) -> int:
    """An integer option (a Python or numpy integer, never a bool or a float that would be rounded)."""
    v = options[key]
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        raise EnvInputError(f"reset options['{key}']: expected an integer, got {type(v).__name__} {v!r}")
    if v < 0:
        raise EnvInputError(f"reset options['{key}']: must be >= 0, got {v}")
    return int(v)


def check_reset_options(options: dict[str, Any], recipe: Recipe) -> None:
    """Refuse reset options the environment would misread, naming the option."""
    unknown = sorted(str(k) for k in options if k not in RESET_OPTIONS)
    if unknown:
        raise EnvInputError(f"reset options: unknown key {unknown[0]!r} (known: {', '.join(RESET_OPTIONS)})")
    if "spec" in options:
        if not isinstance(options["spec"], EpisodeSpec):
            raise EnvInputError(f"reset options['spec']: expected an EpisodeSpec, got {type(options['spec']).__name__}")
        others = sorted(k for k in options if k != "spec")
        if others:
            raise EnvInputError(f"reset options: 'spec' excludes {', '.join(repr(k) for k in others)}")
    if "split" in options and options["split"] not in recipe.splits:
        raise EnvInputError(f"reset options['split']: {options['split']!r} is not a split of recipe {recipe.name} ({', '.join(recipe.splits)})")
    for key in ("index", "attempt"):
        if key in options:
            _int_option(options, key)
    if "attempt" in options and "index" not in options:
        raise EnvInputError("reset options['attempt']: needs 'index' (a fresh draw has no attempts)")


def resolve_recipe(recipe: Recipe | str | Path) -> tuple[Recipe, Path | None]:
    """A Recipe, a recipe YAML path, or a shipped recipe's name ("multi_event") -> (recipe, its folder)."""
    from echo_data.recipe import load_recipe

    if isinstance(recipe, Recipe):
        return recipe, None
    p = Path(recipe)
    if not p.suffix and not p.exists():
        p = SHIPPED_RECIPES / f"{recipe}.yaml"
    return load_recipe(p), p.resolve().parent


def action_space(mode: str = "joint") -> spaces.Box:
    """The action of `mode`: "joint" = the dataset's `action` (base velocities in the robot frame,
    torso and 7 arm joint targets, gripper opening); "ee_delta" = `action.ee` (base velocities and
    torso alike, the TCP change of one step within `ee_control.MAX_EE_STEP` per axis and
    `MAX_EE_TURN` per rotation axis (the map also clips the rotation's norm to it), a binary
    gripper command in [0, 1])."""
    from echo_data.robot import urdf as U
    from echo_data.robot.ee_control import MAX_EE_STEP, MAX_EE_TURN
    from echo_data.robot.robot import MAX_BASE_SPEED, MAX_BASE_TURN

    base_low = [-MAX_BASE_SPEED, -MAX_BASE_SPEED, -MAX_BASE_TURN, U.TORSO_RANGE[0]]
    base_high = [MAX_BASE_SPEED, MAX_BASE_SPEED, MAX_BASE_TURN, U.TORSO_RANGE[1]]
    if mode == "ee_delta":
        low = [*base_low, *[-MAX_EE_STEP] * 3, *[-MAX_EE_TURN] * 3, 0.0]
        high = [*base_high, *[MAX_EE_STEP] * 3, *[MAX_EE_TURN] * 3, 1.0]
        return spaces.Box(np.array(low, np.float32), np.array(high, np.float32), (EE_ACTION_DIM,), np.float32)
    if mode != "joint":
        raise EnvInputError(f"action_mode: {mode!r} is not one of {', '.join(ACTION_SPACES)}")
    arm = [U.ARM_LIMITS[n] for n in U.ARM_JOINTS]
    low = [*base_low, *[a for a, _ in arm], 0.0]
    high = [*base_high, *[b for _, b in arm], 2 * U.FINGER_RANGE[1]]
    return spaces.Box(np.array(low, np.float32), np.array(high, np.float32), (ACTION_DIM,), np.float32)


def observation_space(recipe: Recipe, images: bool = True, audio: bool = True) -> spaces.Dict:
    """Keys, dtypes and shapes of the dataset's observation columns (+ the binaural samples)."""
    from echo_data.acoustics.features import MEL_FLOOR
    from echo_data.dataset.schema import StepLayout

    layout = StepLayout.from_recipe(recipe)
    d: dict[str, spaces.Space] = {}
    if images:
        for col, (kind, h, w) in layout.images.items():
            if kind == "rgb":
                d[col] = spaces.Box(0, 255, (h, w, 3), np.uint8)
            else:
                d[col] = spaces.Box(0, 65535, (h, w), np.uint16)
    d[STATE] = spaces.Box(-np.inf, np.inf, (STATE_DIM,), np.float32)
    if audio:
        hop = recipe.acoustics.sample_rate // recipe.robot.control_hz
        d[BINAURAL] = spaces.Box(-np.inf, np.inf, (hop, 2), np.float32)
        for col, shape in layout.arrays.items():  # log1p magnitudes >= 0; log-mel floored at -100 dB
            low = 0.0 if col == SPECTROGRAM else 10.0 * np.log10(MEL_FLOOR)
            d[col] = spaces.Box(np.float32(low), np.inf, shape, np.float32)
    return spaces.Dict(d)


class EchoDataEnv(gym.Env):
    """Closed-loop episodes of a recipe. See the module docstring."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        recipe: Recipe | str | Path = "multi_event",
        split: str = "test",
        images: bool = True,
        audio: bool = True,
        library: SoundLibrary | None = None,
        recipe_dir: str | Path | None = None,
        render_mode: str | None = None,
        action_mode: str | None = None,
    ) -> None:
        from echo_data.envs.workers import pin_worker_threads

        pin_worker_threads()  # a vector env's worker process: one thread per pool (no-op in the main process)
        self.recipe, rdir = resolve_recipe(recipe)
        self.action_mode = self.recipe.robot.action_space if action_mode is None else action_mode
        if self.action_mode not in ACTION_SPACES:
            raise EnvInputError(f"action_mode: {self.action_mode!r} is not one of {', '.join(ACTION_SPACES)}")
        self.recipe_dir = Path(recipe_dir) if recipe_dir is not None else rdir
        if split not in ("train", "val", "test"):
            raise EnvInputError(f"split: {split!r} is not one of train, val, test")
        self.split = split
        self.images = images
        self.audio = audio
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.recipe.robot.control_hz}
        self._library = library
        self.observation_space: spaces.Dict = observation_space(self.recipe, images, audio)
        self.action_space = action_space(self.action_mode)
        self._world: World | None = None
        self.track: Any = None
        self._episode: EpisodeSpec | None = None
        self._obs: dict[str, np.ndarray] = {}

    @property
    def world(self) -> World:
        """The current episode's world (after `reset`)."""
        if self._world is None:
            raise EnvInputError("no episode: call reset() first")
        return self._world

    @property
    def episode(self) -> EpisodeSpec:
        """The current episode's spec (after `reset`)."""
        if self._episode is None:
            raise EnvInputError("no episode: call reset() first")
        return self._episode

    # ------------------------------------------------------------------ episode
    @property
    def library(self) -> SoundLibrary:
        if self._library is None:
            from echo_data.sounds import SoundLibrary

            self._library = SoundLibrary.from_recipe(self.recipe, self.recipe_dir)
        return self._library

    def sample_spec(self, split: str, index: int, attempt: int = 0) -> EpisodeSpec:
        """The spec `echo-data build` samples for (recipe seed, split, index, attempt)."""
        from echo_data.scene.sampling import sample_episode

        size = self.recipe.splits.get(split, 0)
        if not 0 <= index < size:
            raise EnvInputError(f"index: {index} is outside the {split} split of recipe {self.recipe.name} ({size} episodes)")
        spec, _ = sample_episode(self.recipe, split, int(index), self.library, attempt=int(attempt))
        return spec

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        """Enter an episode: options {"spec": EpisodeSpec} | {"split", "index"[, "attempt"]}; else a fresh draw."""
        super().reset(seed=seed)
        if options is not None and not isinstance(options, dict):
            raise EnvInputError(f"reset options: expected a dict, got {type(options).__name__}")
        options = dict(options or {})
        check_reset_options(options, self.recipe)
        if "spec" in options:
            spec = options["spec"]
        elif "index" in options:
            spec = self.sample_spec(options.get("split", self.split), options["index"], options.get("attempt", 0))
        else:  # a fresh episode: the recipe under another seed, both drawn from the seeded generator
            from echo_data.scene.sampling import sample_episode

            split = options.get("split", self.split)
            fresh = self.recipe.model_copy(update={"seed": int(self.np_random.integers(2**31))})
            index = int(self.np_random.integers(max(self.recipe.splits.get(split, 1), 1)))
            spec, _ = sample_episode(fresh, split, index, self.library)
        self._start(spec)
        return self._obs, self._info(reset=True)

    def _start(self, spec: EpisodeSpec) -> None:
        from echo_data.world import World

        self._close_world()
        self._episode = spec
        self._world = World(spec, self.recipe, render=self.images)
        self.sounding = [True] * len(spec.events)
        self.resolved_step: list[int | None] = [None] * len(spec.events)
        self.door_changes: list[tuple[int, dict[int, float]]] = []
        self.progress = 0  # true-chain skills completed in order (latched)
        self.steps = 0
        self.failure = ""
        self.ended = ""  # "terminated" or "truncated" once the episode is over: step() then refuses
        self.agent_stops = False  # True: the active skill ends only at `stop_skill()` (SoundSpaces' STOP)
        self._grids: dict[tuple, Any] = {}
        self._resolver = {call.event: k for k, call in enumerate(spec.chain) if SKILLS[call.skill].resolves_event}
        self.max_episode_steps = sum(skill_budget(self.recipe, c.skill) for c in spec.chain)
        self._situation = Situation(spec, self.nav_grid)
        self._handover_to = [handover_call(spec.chain, k) for k in range(len(spec.chain))]
        self.success_flags = self._evaluate()
        self.handover_flags = self._handed_over()
        self.track = None
        heard = None
        if self.audio:
            from echo_data.envs.audio import OnlineTrack

            self.track = OnlineTrack(spec, self.recipe, self.library)
            self.track.pre_roll(self.ear_pose())
            heard = self.track.heard()
        self._advance()  # a skill whose test holds from the start counts from the start
        self._obs = self._observe(heard)

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        if self._world is None:
            raise EnvInputError("step() before reset()")
        if self.ended:
            raise EnvInputError(f"step(): the episode {self.ended} at step {self.steps}; call reset() first")
        a = as_action(action, EE_ACTION_DIM if self.action_mode == "ee_delta" else ACTION_DIM)
        if not np.all(np.isfinite(a)):
            self.failure = f"non-finite action at step {self.steps}"
            self.ended = "terminated"
            return self._obs, 0.0, True, False, self._info()
        if self.action_mode == "ee_delta":  # the one ee map, from the commanded state (float32 joint targets)
            a = self.world.robot.ee.to_joint(a)
        pose = self.ear_pose()  # the head during this control period
        self.world.step(a)
        self.steps += 1
        self.success_flags = self._evaluate()  # the one evaluation of this step: events, progress, reward, info
        self.handover_flags = self._handed_over()
        newly = self._update_events()
        heard = None
        if self.track is not None:  # heard on the listening thread while the cameras render (`_observe` waits for it)
            doors = [self.world.door_angles() for e in newly if self._opens_door(e)]
            heard = self.track.hear_soon(pose, doors, newly)
        for e in newly:
            if self._opens_door(e):
                self.door_changes.append((self.steps, self.world.door_angles()))
        before = self.progress
        self._advance()
        self._obs = self._observe(heard)
        terminated = self.progress == len(self.episode.chain)
        truncated = not terminated and self.steps >= self.max_episode_steps
        self.ended = "terminated" if terminated else "truncated" if truncated else ""
        return self._obs, float(self.progress - before), terminated, truncated, self._info()

    def _update_events(self) -> list[int]:
        """Events whose resolving skill's success test holds now (latched): they stop sounding."""
        newly = []
        for e, k in self._resolver.items():
            if self.sounding[e] and self.success_flags[k]:
                self.sounding[e] = False
                self.resolved_step[e] = self.steps
                newly.append(e)
        return sorted(newly)

    def _opens_door(self, event: int) -> bool:
        return SKILLS[self.episode.chain[self._resolver[event]].skill].effect == "opens_door"

    def _advance(self) -> None:
        """Count the chain's skills whose tests hold, in order (not while the agent ends the active one itself)."""
        while not self.agent_stops and self.progress < len(self.episode.chain) and self.success_flags[self.progress]:
            self._complete()

    def _complete(self) -> None:
        apply_effect(self.world, self.episode.chain[self.progress], self.episode)  # e.g. a placed object rests on its goal
        self.progress += 1

    def stop_skill(self) -> tuple[dict, float, bool, bool, dict]:
        """SoundSpaces' STOP for the active skill, for an agent that ends its skills itself
        (`agent_stops`): no physics step; the skill's success test on the current state (this
        step's evaluation) decides: it holds -> the skill counts (reward 1, the next one becomes
        active; `terminated` after the last), else the episode ends failed (`info["failure"]`)."""
        if self._world is None:
            raise EnvInputError("stop_skill() before reset()")
        if self.ended:
            raise EnvInputError(f"stop_skill(): the episode {self.ended} at step {self.steps}; call reset() first")
        if not self.agent_stops:
            raise EnvInputError("stop_skill(): set agent_stops = True first (else skills count the step their tests hold)")
        call = self.episode.chain[self.progress]
        if self.success_flags[self.progress]:
            self._complete()
            reward = 1.0
        else:
            self.failure = f"stopped at step {self.steps}: {call.skill}({call.target}) success test false"
            reward = 0.0
        terminated = bool(self.failure) or self.progress == len(self.episode.chain)
        self.ended = "terminated" if terminated else ""
        return self._obs, reward, terminated, False, self._info()

    # ------------------------------------------------------------------ observations
    def ear_pose(self) -> tuple[float, float, float, float]:
        (x, y, z), yaw = self.world.robot.ear_pose()
        return (float(x), float(y), float(z), float(yaw))

    def _observe(self, heard: Future[Heard] | None) -> dict[str, np.ndarray]:
        from echo_data.dataset.schema import IMAGE_COLUMNS

        obs: dict[str, np.ndarray] = {}
        if self.images:
            pics = self.world.observe()
            for key, col in IMAGE_COLUMNS.items():
                if col in self.observation_space.spaces:
                    obs[col] = pics[key]
        obs[STATE] = self.world.robot.state().astype(np.float32)
        if heard is not None:
            block, spec, mel = heard.result()
            obs[BINAURAL] = np.asarray(block, dtype=np.float32)
            if SPECTROGRAM in self.observation_space.spaces:
                obs[SPECTROGRAM] = spec
            if MEL in self.observation_space.spaces:
                obs[MEL] = mel
        return obs

    def _info(self, reset: bool = False) -> dict[str, Any]:
        spec = self.episode
        assert spec is not None
        info: dict[str, Any] = {
            "episode_id": spec.episode_id,
            "setting": spec.setting,
            "steps": self.steps,
            "events": [
                {"category": ev.category, "target": ev.target, "sounding": self.sounding[e], "resolved_step": self.resolved_step[e]}
                for e, ev in enumerate(spec.events)
            ],
            "skills": [
                {"skill": c.skill, "target": c.target, "event": c.event, "success": self.success_flags[k], "done": k < self.progress,
                 "handed_over": self.handover_flags[k]}
                for k, c in enumerate(spec.chain)
            ],
            "active_skill": spec.chain[self.progress].skill if self.progress < len(spec.chain) else None,
            "active_skill_index": self.progress,
            "success": self.progress == len(spec.chain),
        }
        if self.failure:
            info["failure"] = self.failure
        if reset:
            info["spec"] = spec.to_dict()
        return info

    # ------------------------------------------------------------------ success tests
    def _evaluate(self) -> list[bool]:
        """Every chain skill's success test on the current state, once (`echo_data.skill_table`)."""
        return [SKILLS[c.skill].success(self.world, c, self._situation) for c in self.episode.chain]

    def _handed_over(self) -> list[bool]:
        """Per chain entry, whether its drive has handed over (docs/handover.md): an approach
        skill's success test holds and the base stands inside the next skill's stance; a skill
        that drives itself (Place's carry) stands inside its own; False where none follows."""
        chain = self.episode.chain
        return [to is not None and (to is chain[k] or self.success_flags[k]) and in_stance(self.world, to, self._situation)
                for k, to in enumerate(self._handover_to)]

    def in_stance_centre(self, k: int) -> bool:
        """Whether chain entry `k`'s drive stands in the centre of the stance it hands over to
        (`skill_table.STANCE_CENTRE` of it) with its success test holding: where a learned drive
        ending "centre" stops (`agents.runtime.DRIVE_ENDS`)."""
        to = self._handover_to[k]
        return bool(to is not None and self.handover_flags[k] and in_stance(self.world, to, self._situation, STANCE_CENTRE))

    def skill_success(self, call: SkillCall) -> bool:
        """The success test of `call` on the current state, evaluated now (the runtime reads
        `info["skills"]`, which holds the step's one evaluation)."""
        return SKILLS[call.skill].success(self.world, call, self._situation)

    def nav_grid(self) -> Any:
        """Navigation grid at the doors' current angles (cached per angle to 1 mrad, ~1 mm at a door's edge)."""
        from echo_data.scene.nav import NavGrid

        angles = self.world.door_angles()
        key = tuple(sorted((i, round(a, 3)) for i, a in angles.items()))
        grid = self._grids.get(key)
        if grid is None:
            radius = self.world.nav.robot_radius
            grid = NavGrid.from_plan(self.world.plan, robot_radius=radius, door_angles={i: a for i, a in key})
            self._grids[key] = grid
        return grid

    # ------------------------------------------------------------------ misc
    def episode_audio(self) -> tuple[np.ndarray, np.ndarray]:
        """The whole episode track (tails rung out) and each recorded observation's sample offset."""
        if self.track is None:
            raise EnvInputError("episode_audio(): the environment was made with audio=False")
        return self.track.finish(), self.track.offsets(self.steps)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array" or self._world is None:
            return None
        from echo_data.dataset.schema import IMAGE_COLUMNS

        col = IMAGE_COLUMNS["head_rgb"]
        if col in self._obs:
            return self._obs[col]
        return self.world.observe().get("head_rgb") if self.images else None

    def _close_world(self) -> None:
        if self._world is not None:
            self._world.close()
        self._world = None

    def close(self) -> None:
        self._close_world()

