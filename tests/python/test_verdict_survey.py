"""scripts/verdict_survey.py: every record has its documented-play class, and the summary counts and flags."""
import data_records
import verdict_survey


def test_every_record_of_every_set_has_a_documented_play_class_of_its_own():
    records = {**data_records.manifest(), **data_records.manifest(extra=True),
               **data_records.manifest(survey=True)}
    for record in records:
        folder = record.split("/")[0]
        assert record in verdict_survey.PLAY_DOCUMENTED or folder in verdict_survey.PLAY_DOCUMENTED, record
        assert verdict_survey.play_documented(record) in verdict_survey.CLASSES
    assert verdict_survey.play_documented("f16gvt/f16gvt_sinesweep_level7.csv") == "yes"
    assert verdict_survey.play_documented("f16gvt/f16gvt_sinesweep_level1.csv") == "no"
    assert verdict_survey.play_documented("brfd/KocaeliDBE_36lb.csv") == "yes"


def row(record: str, cls: str, presence: str, seed: str = "0") -> dict[str, str]:
    return {"set": "survey", "record": record, "play_documented": cls, "seed": seed, "fit_fraction": "0.7",
            "presence": presence, "play": "0.1", "play_se": "0.01", "play_bound": "", "undecided_by": "",
            "seconds": "1.0"}


def test_the_summary_counts_per_class_and_flags_contradictions_and_moving_verdicts():
    rows = [row("a/one.csv", "yes", "present"), row("a/one.csv", "yes", "absent", seed="1"),
            row("b/two.csv", "no", "present"), row("c/three.csv", "unknown", "undetermined")]
    text = verdict_survey.summary(rows)
    assert "| yes | 2 | 1 | 1 | 0 | 0 |" in text and "| no | 1 | 1 | 0 | 0 | 0 |" in text
    assert "| unknown | 1 | 0 | 0 | 1 | 0 |" in text
    assert "seeds and fractions: 1" in text and "0/0.7: present, 1/0.7: absent" in text
    flagged = text.split("### Flagged")[1]
    assert "b/two.csv" in flagged and "| a/one.csv | yes | 1 |" in flagged and "c/three.csv" not in flagged
