// The panel that shows a picked building's properties (its row of the content's property table),
// shared by the CesiumJS and 3d-tiles-renderer pages. `props` is null when nothing is picked.
function citymeshShowPicked(panel, state, props) {
  state.picked = props;
  panel.replaceChildren();
  if (!props) { panel.hidden = true; return; }
  panel.hidden = false;
  const title = document.createElement('b');
  title.textContent = `${props.osm_type}/${props.osm_id}`;
  panel.append(title);
  for (const [k, v] of Object.entries(props)) {
    if (v === undefined || v === null || v === '' || k === 'osm_type' || k === 'osm_id') continue;
    const row = document.createElement('div');
    row.textContent = `${k}: ${v}`;
    panel.append(row);
  }
}
