"""Every physics family reads its parameter file's head alike (vessel_physics.files)."""

import pytest

from vessel_physics.errors import ConfigError
from vessel_physics.fossen.params import FORMAT as FOSSEN
from vessel_physics.fossen.params import params_from_dict as fossen
from vessel_physics.mmg.params import FORMAT as MMG
from vessel_physics.mmg.params import params_from_dict as mmg
from vessel_physics.multirotor.params import FORMAT as MULTIROTOR
from vessel_physics.multirotor.params import params_from_dict as multirotor
from vessel_physics.patrol.params import FORMAT as PATROL
from vessel_physics.patrol.params import params_from_dict as patrol

FAMILIES = [(fossen, FOSSEN), (mmg, MMG), (multirotor, MULTIROTOR), (patrol, PATROL)]


@pytest.mark.parametrize(('read', 'fmt'), FAMILIES)
def test_another_format_or_no_mapping_is_refused_in_one_line(read, fmt):
    with pytest.raises(ConfigError) as refused:
        read({'format': fmt + 'x', 'name': 'boat'}, 'boat.yaml')
    assert str(refused.value) == f"boat.yaml: format: expected {fmt!r}, got {fmt + 'x'!r}"
    with pytest.raises(ConfigError) as refused:
        read(['name', 'boat'], 'boat.yaml')
    assert str(refused.value).startswith('boat.yaml: expected a mapping of ')
    assert str(refused.value).endswith('parameters, got list')


@pytest.mark.parametrize(('read', 'fmt'), FAMILIES)
def test_what_a_file_says_of_itself_is_no_parameter(read, fmt):
    # Past the head, the first thing a family checks names a parameter, never these keys.
    with pytest.raises(ConfigError) as refused:
        read({'format': fmt, 'description': 'a boat', 'sources': ['a book']}, 'boat.yaml')
    message = str(refused.value)
    assert 'description' not in message and 'sources' not in message, message
