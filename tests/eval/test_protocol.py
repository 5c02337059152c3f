"""The protocol lock and ledger: test splits run only with --final under a matching lock, every
such run is in the ledger, and no test object id is written into library code or configs."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest
import yaml

from actaim2.cli import main as cli
from actaim2.eval.evalset import EVAL_SET_VERSION
from actaim2.eval.paired import component_groups
from actaim2.protocol.lock import (
    ProtocolLock,
    append_ledger,
    check_run,
    file_sha256,
    guarded_ids,
    protected,
    read_ledger,
    success_rule,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim"))
from partnet_shared import shared_partnet  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
COMMITTED = REPO / "actaim2_policy" / "checkpoints" / "actaim2_ring5"
SEED0, SEED1, SEED2 = "a" * 64, "b" * 64, "f" * 64


def lock(**changes) -> ProtocolLock:
    fields = dict(
        recipe="recipe.yaml",
        recipe_sha256="c" * 64,
        checkpoints=(SEED0, SEED1, SEED2),
        eval_set_version=EVAL_SET_VERSION,
        samples_per_group=8,
        objects={"test_unseen_category": ("100154", "9968"), "test_unseen_instance": ("156",)},
        success_rule=success_rule(),
    )
    return ProtocolLock(**{**fields, **changes})


def test_a_lock_checks_itself_and_round_trips(tmp_path) -> None:
    path = tmp_path / "results" / "protocol.lock"
    lock().write(path)
    assert ProtocolLock.read(path) == lock() and ProtocolLock.read(path).sha256 == lock().sha256
    assert json.loads(path.read_text())["success_rule"]["fraction"] == 0.3
    with pytest.raises(ValueError, match="written once"):
        lock().write(path)
    for bad, words in (
        ({"checkpoints": ("d2ca9126", SEED0, SEED1)}, "64 hex"),
        ({"checkpoints": (SEED0, SEED0, SEED1)}, "same checkpoint"),
        ({"checkpoints": (SEED0, SEED1)}, "at least 3 seeds"),
        ({"samples_per_group": 1}, "both halves"),
        ({"objects": {"val": ("149",)}}, "test splits"),
        ({"objects": {"test_unseen_instance": ()}}, "non-empty"),
        ({"recipe_sha256": "x"}, "sha256"),
    ):
        with pytest.raises(ValueError, match=words):
            lock(**bad)
    with pytest.raises(ValueError, match="no protocol lock"):
        ProtocolLock.read(tmp_path / "none.lock")
    (tmp_path / "broken.lock").write_text("{}")
    with pytest.raises(ValueError, match="not a protocol lock"):
        ProtocolLock.read(tmp_path / "broken.lock")


def test_test_objects_are_known_by_split_or_by_folder(tmp_path) -> None:
    (tmp_path / "splits.yaml").write_text(
        "'156': test_unseen_instance\n'149': val\n'9968': test_unseen_category\n"
    )
    ids = guarded_ids([tmp_path / "splits.yaml", tmp_path / "missing.yaml"])
    assert ids == {"156": "test_unseen_instance", "9968": "test_unseen_category"}
    objects = [
        ("folders", "156"),
        ("val", "149"),
        ("train_seen", ""),
        ("test_unseen_category", "100154"),
    ]
    assert protected(objects, ids) == {
        "test_unseen_instance": {"156"},
        "test_unseen_category": {"100154"},
    }
    assert protected([("test_unseen_category", "")], {}) == {"test_unseen_category": set()}
    assert protected([("val", "149"), ("heldout_category", "")], ids) == {}


def test_a_final_run_must_match_the_lock(tmp_path) -> None:
    path = tmp_path / "protocol.lock"
    guarded = {"test_unseen_instance": {"156"}}
    with pytest.raises(ValueError, match="without --final"):
        check_run("evaluate", guarded, False, path, [SEED0])
    with pytest.raises(ValueError, match="no protocol lock"):
        check_run("evaluate", guarded, True, path, [SEED0])
    with pytest.raises(ValueError, match="for test splits"):
        check_run("evaluate", {}, True, path, [SEED0])
    assert check_run("evaluate", {}, False, path, [SEED0]) is None
    lock().write(path)
    assert check_run("evaluate", guarded, True, path, [SEED1], EVAL_SET_VERSION, 8) == lock()
    for args, words in (
        (([SEED0], EVAL_SET_VERSION + 1, 8), "evaluation set version"),
        (([SEED0], EVAL_SET_VERSION, 4), "4 samples"),
        ((["e" * 64], EVAL_SET_VERSION, 8), "not among the lock's seeds"),
        (([], None, None), "none"),
    ):
        with pytest.raises(ValueError, match=words):
            check_run("evaluate", guarded, True, path, *args)
    with pytest.raises(
        ValueError, match=r"missing \['9968'\]"
    ):  # a test object dropped after the lock
        check_run("evaluate", {"test_unseen_category": {"100154"}}, True, path, [SEED0])
    with pytest.raises(ValueError, match=r"not locked \['101'\]"):
        check_run("validate", {"test_unseen_instance": {"156", "101"}}, True, path, [SEED0])
    changed = lock(success_rule={**success_rule(), "fraction": 0.1})
    (tmp_path / "other.lock").write_text(json.dumps(changed.to_json()))
    with pytest.raises(ValueError, match="success rule"):
        check_run("evaluate", guarded, True, tmp_path / "other.lock", [SEED0])


def test_every_final_run_is_in_the_ledger(tmp_path, capsys) -> None:
    ledger = tmp_path / "results" / "ledger.jsonl"
    assert read_ledger(ledger) == []
    assert cli(["protocol", "ledger", "--ledger", str(ledger)]) == 0
    assert capsys.readouterr().out.startswith("0 --final run(s)")
    for tool in ("evaluate", "validate"):
        append_ledger(
            ledger, lock(), tool, "runs/x", {"test_unseen_instance": {"156"}}, [SEED0], 120
        )
    runs = read_ledger(ledger)
    assert [r["tool"] for r in runs] == ["evaluate", "validate"] and runs[0][
        "lock_sha256"
    ] == lock().sha256
    assert runs[0]["splits"] == {"test_unseen_instance": ["156"]} and runs[1]["samples"] == 120
    assert cli(["protocol", "ledger", "--ledger", str(ledger)]) == 0
    assert capsys.readouterr().out.startswith("2 --final run(s)")
    ledger.write_text(ledger.read_text() + "not json\n")
    with pytest.raises(ValueError, match=":3: not a JSON line"):
        read_ledger(ledger)


@pytest.mark.skipif(not COMMITTED.with_suffix(".json").is_file(), reason="no committed checkpoint")
def test_protocol_lock_command_writes_the_catalogues_test_objects(tmp_path, capsys) -> None:
    root = shared_partnet()
    recipe = tmp_path / "recipe.yaml"
    recipe.write_text("config: cpu_default\n")
    meta = json.loads(COMMITTED.with_suffix(".json").read_text())
    seeds = [COMMITTED]
    for k in (1, 2):  # two more seeds' checkpoints: the lock reads their JSON only
        seeds.append(tmp_path / f"seed{k}")
        other = {**meta, "weights_sha256": str(k) * 64}
        seeds[-1].with_suffix(".json").write_text(json.dumps(other))
    path = tmp_path / "protocol.lock"
    base = ["protocol", "lock", "--recipe", str(recipe), "--lock", str(path),
            "--partnet-root", str(root), "--checkpoint", str(COMMITTED)]
    assert cli(base) == 2 and "--catalogue partnet" in capsys.readouterr().err
    assert cli(base + ["--catalogue", "partnet"]) == 2
    assert "at least 3 seeds" in capsys.readouterr().err
    base += ["--catalogue", "partnet"]
    base += ["--checkpoint", str(seeds[1]), "--checkpoint", str(seeds[2])]
    assert cli(base + ["--splits", "val"]) == 2 and "test splits only" in capsys.readouterr().err
    assert cli(base) == 0 and not capsys.readouterr().err
    written = ProtocolLock.read(path)
    listed = yaml.safe_load((root / "splits.yaml").read_text())
    for split in ("test_unseen_instance", "test_unseen_category"):
        assert sorted(written.objects[split]) == sorted(k for k, v in listed.items() if v == split)
    assert written.checkpoints == (meta["weights_sha256"], "1" * 64, "2" * 64)
    assert written.recipe_sha256 == file_sha256(recipe)
    assert (written.eval_set_version, written.samples_per_group) == (EVAL_SET_VERSION, 8)
    assert written.success_rule == success_rule()
    assert cli(base) == 2 and "written once" in capsys.readouterr().err


def test_evaluate_refuses_a_test_split_without_final_and_lock(tmp_path, capsys) -> None:
    root = shared_partnet()
    base = ["evaluate", "--out", str(tmp_path / "eval"), "--methods", "random",
            "--render-path", "raycast", "--lock", str(tmp_path / "protocol.lock"),
            "--ledger", str(tmp_path / "ledger.jsonl"), "--no-progress"]
    partnet = base + ["--catalogue", "partnet", "--partnet-root", str(root)]
    assert cli(partnet + ["--splits", "test_unseen_category"]) == 2
    err = capsys.readouterr().err
    assert "refuses test-split objects" in err and "test_unseen_category" in err
    assert "--final" in err
    # a test object given as a folder is known by the splits file beside it
    assert cli(base + ["--splits", "", "--objects", str(root / "156")]) == 2
    assert "test_unseen_instance: 156" in capsys.readouterr().err
    final = ["--splits", "test_unseen_instance", "--final", "--per-group", "8"]
    assert cli(partnet + final) == 2
    assert "no protocol lock" in capsys.readouterr().err
    assert cli(partnet + ["--splits", "val", "--final"]) == 2
    assert "for test splits" in capsys.readouterr().err
    assert not (tmp_path / "eval").exists() and not (tmp_path / "ledger.jsonl").exists()


def test_no_test_object_id_in_library_code_or_configs() -> None:
    listed = yaml.safe_load((shared_partnet() / "splits.yaml").read_text())
    ids = sorted(k for k, v in listed.items() if v.startswith("test_"))
    pattern = re.compile(r"(?<![\w.\-])(" + "|".join(map(re.escape, ids)) + r")(?![\w.])")
    places = [REPO / "src"] + sorted(REPO.glob("actaim2_*")) + [REPO / "scripts", REPO / "tools"]
    found = []
    for place in places:
        for path in place.rglob("*"):
            if (
                path.suffix in (".py", ".yaml", ".yml", ".json", ".sh", ".cfg", ".toml", ".xml")
                and path.is_file()
            ):
                found += [
                    f"{path.relative_to(REPO)}: {m.group(0)}"
                    for m in pattern.finditer(path.read_text(errors="replace"))
                ]
    assert not found, found


def _write_run(folder: Path, seed: int) -> None:
    """One seed's evaluation records on six objects of two categories: ActAIM2's clusters 0-1
    always close and 2-3 always open; Data Collection's eight pseudo-clusters never succeed."""
    folder.mkdir(parents=True)
    lines = []
    for k in range(6):
        obj, category = f"folder:{900 + k}", ("box", "laptop")[k % 2]
        for method, groups in (("actaim2", 4), ("data_collection", 8)):
            for slot in range(groups * 4):
                group, repetition = slot % groups, slot // groups
                works = method == "actaim2"
                mode = (["joint_0", -1] if group < 2 else ["joint_0", 1]) if works else None
                lines.append({"key": f"{method}|{obj}|{slot}", "method": method, "object": obj,
                              "split": "test_unseen_category", "category": category,
                              "slot": slot, "reset_seed": 1000 * seed + slot, "success": works, "group": group,
                              "repetition": repetition, "mode": mode})
    (folder / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))


def test_protocol_compare_applies_both_rules_over_seeds(tmp_path, capsys) -> None:
    runs = [tmp_path / f"s{k}" for k in range(2)]
    for k, run in enumerate(runs):
        _write_run(run, k)
    out = tmp_path / "compare.md"
    args = ["protocol", "compare", *map(str, runs), "--rounds", "200", "--out", str(out)]
    assert cli(args) == 0
    text = capsys.readouterr().out
    assert text.strip() == out.read_text().strip()
    exact = "+100.0 [+100.0, +100.0]"
    assert f"| SSR, paired scenes | {exact} | {exact} | yes |" in text
    assert "2nd-mode SSR, 100 halvings (positive in 100 %) | +100.0 [+100.0, +100.0]" in text
    assert text.count("| 100.0 [") == 2 and text.count("| 0.0 [") == 2  # each seed's SSRs
    assert cli(args + ["--method", "data_collection", "--baseline", "actaim2"]) == 0
    assert "| -100.0 [-100.0, -100.0] | no |" in capsys.readouterr().out
    assert cli(["protocol", "compare", str(tmp_path / "none")]) == 2
    assert "no results.jsonl" in capsys.readouterr().err

    assert "by its GMM components" not in text  # pseudo-clusters only: no component was recorded

    # Data Collection whose GMM has 2 components: slot s drew from component s mod 2, and
    # component 0 always closes the object: by its own components it has a 1st mode that always
    # works and a 2nd that never does.
    comp = tmp_path / "components"
    records = [json.loads(t) for t in (runs[0] / "results.jsonl").read_text().splitlines()]
    for r in records:
        if r["method"] == "data_collection":
            works = r["slot"] % 2 == 0
            r.update(gmm_clusters=2, success=works, mode=["joint_0", -1] if works else None)
    comp.mkdir()
    (comp / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    assert cli(["protocol", "compare", str(comp), "--rounds", "200"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| 2nd")]
    assert len(rows) == 2 and "by its GMM components" in rows[1]
    by_component = rows[1]
    assert f"| {exact} | {exact} | yes |" in by_component  # its 2nd component never succeeds
    grouped = component_groups(records, "data_collection")
    assert all(r["group"] == r["slot"] % 2 and r["repetition"] == r["slot"] // 2
               for r in grouped if r["method"] == "data_collection")
    assert [r for r in grouped if r["method"] == "actaim2"] == [r for r in records if r["method"] == "actaim2"]

    # The baseline evaluated once in a folder of its own: the same verdict as beside the method.
    split = tmp_path / "split"
    for k, run in enumerate(runs):
        records = [json.loads(t) for t in (run / "results.jsonl").read_text().splitlines()]
        for method in ("actaim2", "data_collection"):
            (split / method / f"s{k}").mkdir(parents=True)
            (split / method / f"s{k}" / "results.jsonl").write_text(
                "".join(json.dumps(r) + "\n" for r in records if r["method"] == method))
    separate = ["protocol", "compare", *(str(split / "actaim2" / f"s{k}") for k in range(2)), "--rounds", "200",
                "--baseline-from", *(str(split / "data_collection" / f"s{k}") for k in range(2))]
    assert cli(separate) == 0
    assert f"| SSR, paired scenes | {exact} | {exact} | yes |" in capsys.readouterr().out
    assert cli(separate + [str(split / "data_collection" / "s0")]) == 2
    assert "3 folders for 2 runs" in capsys.readouterr().err


@pytest.mark.skipif(not COMMITTED.with_suffix(".json").is_file(), reason="no committed checkpoint")
def test_a_final_run_under_a_lock_runs_once_per_ledger_line(tmp_path, capsys) -> None:
    """The whole path on a one-object catalogue: lock, --final evaluation (ActAIM2, 2 per group,
    ray casting), a ledger line before it runs, another for a resumed run, none for a refusal."""
    root = tmp_path / "pm"
    root.mkdir()
    (root / "156").symlink_to(shared_partnet() / "156")
    (root / "splits.yaml").write_text("'156': test_unseen_instance\n")
    (tmp_path / "recipe.yaml").write_text("config: cpu_default\n")
    meta = json.loads(COMMITTED.with_suffix(".json").read_text())
    seeds = [str(COMMITTED)]
    for k in (1, 2):
        other = {**meta, "weights_sha256": str(k) * 64}
        (tmp_path / f"seed{k}.json").write_text(json.dumps(other))
        seeds.append(str(tmp_path / f"seed{k}"))
    lock, ledger = tmp_path / "protocol.lock", tmp_path / "ledger.jsonl"
    partnet = ["--catalogue", "partnet", "--partnet-root", str(root)]
    assert cli(["protocol", "lock", *partnet, "--recipe", str(tmp_path / "recipe.yaml"),
                "--lock", str(lock), "--samples-per-group", "2",
                "--splits", "test_unseen_instance",
                *[a for s in seeds for a in ("--checkpoint", s)]]) == 0
    run = ["evaluate", "--out", str(tmp_path / "eval"), "--checkpoint", str(COMMITTED),
           "--methods", "actaim2", *partnet, "--splits", "test_unseen_instance", "--final",
           "--quick", "--render-path", "raycast", "--workers", "0", "--figures", "0",
           "--videos", "0", "--no-progress", "--lock", str(lock), "--ledger", str(ledger)]
    assert cli(run + ["--per-group", "4"]) == 2  # not the lock's samples per group
    assert "4 samples per group, the lock's is 2" in capsys.readouterr().err
    assert not ledger.exists()
    assert cli(run + ["--per-group", "2"]) == 0
    (line,) = read_ledger(ledger)
    assert line["splits"] == {"test_unseen_instance": ["156"]} and line["samples"] == 16
    assert line["checkpoints"] == [meta["weights_sha256"]] and line["tool"] == "evaluate"
    results = (tmp_path / "eval" / "results.jsonl").read_text().splitlines()
    records = [json.loads(t) for t in results]
    assert len(records) == 16 and {r["split"] for r in records} == {"test_unseen_instance"}
    assert "Real, unseen instances (test)" in (tmp_path / "eval" / "tables.md").read_text()
    assert cli(run + ["--per-group", "2"]) == 0  # resumed: nothing left to run, still a line
    assert [r["samples"] for r in read_ledger(ledger)] == [16, 0]
    capsys.readouterr()
    assert cli(["protocol", "ledger", "--ledger", str(ledger)]) == 0
    assert capsys.readouterr().out.startswith("2 --final run(s)")
