// When the page's libraries (npm packages citymesh serves under /vendor/) do not load, say on
// the page what to run instead of leaving it blank. `note` is an optional first sentence.
function citymeshAssetsMissing(what, from, note) {
  const show = () => {
    if (document.getElementById('assets-missing')) return;
    const box = document.createElement('div');
    box.id = 'assets-missing';
    box.setAttribute('role', 'alert');
    box.style.cssText = 'position:fixed;top:16px;left:50%;transform:translateX(-50%);z-index:1000;'
      + 'max-width:640px;padding:12px 18px;background:#fff4f2;color:#2a0a0a;border:2px solid #c01c28;'
      + 'border-radius:6px;font:14px/1.5 system-ui,sans-serif;box-shadow:0 2px 10px rgba(0,0,0,0.35)';
    const title = document.createElement('strong');
    title.textContent = `${what} did not load (${from}).`;
    const why = document.createElement('p');
    why.textContent = (note ? note + ' ' : '') + 'citymesh serves the npm packages of its '
      + 'repository under /vendor/ (from --assets-dir, by default node_modules in the directory '
      + 'the server was started in). Install them by running this in the citymesh repository:';
    const command = document.createElement('pre');
    command.style.cssText = 'margin:4px 0;padding:6px 10px;background:#f2f2f2;font-size:15px';
    command.textContent = 'npm ci';
    const then = document.createElement('p');
    then.style.margin = '0';
    then.textContent = 'Then reload this page. If the server was started from another directory, '
      + 'restart it with --assets-dir /path/to/citymesh/node_modules (or CITYMESH_ASSETS_DIR).';
    box.append(title, why, command, then);
    document.body.appendChild(box);
  };
  if (document.body) show(); else addEventListener('DOMContentLoaded', show);
}
