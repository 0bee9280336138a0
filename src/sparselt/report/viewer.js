/* sparselt image viewer (sparselt.report.viewer): comparison slider, zoom and pan, exposure, error view.
 * Plain ES2017, no dependencies, no network. One global: window.sparseltViewer = {init: function (element)}.
 * Each .sparselt-viewer keeps its state in a closure and mirrors it on its element (data-slider, data-view,
 * data-zoom, data-pan-x, data-pan-y, data-exposure, data-left, data-right, data-ready, data-broken). */
(function () {
  'use strict';
  if (window.sparseltViewer) {
    return;
  }

  var MINIMUM_ZOOM = 1;
  var MAXIMUM_ZOOM = 64;
  var BUTTON_ZOOM = Math.SQRT2;
  var KEY_STEP = 0.05;
  var FINE_KEY_STEP = 0.01;
  var MINIMUM_DISPLAY_WIDTH = 480;
  var SIDES = ['left', 'right'];

  function clamp(value, low, high) {
    return Math.min(high, Math.max(low, value));
  }

  function rounded(value) {
    return String(Math.round(value * 10000) / 10000);
  }

  function init(root) {
    if (!root || root.getAttribute('data-initialised') === 'true') {
      return;
    }
    root.setAttribute('data-initialised', 'true');

    function part(role) {
      return root.querySelector('[data-role="' + role + '"]');
    }

    var data = JSON.parse(part('data').textContent);
    var images = data.images;
    var stage = part('stage');
    var divider = part('divider');
    var errorToggle = part('error-toggle');
    var exposureInput = part('exposure');
    var exposureValue = part('exposure-value');
    var zoomValue = part('zoom-value');
    var legend = part('legend');
    var warning = part('warning');
    var gains = Array.prototype.slice.call(root.querySelectorAll('[data-role="exposure-gain"]'));
    var layers = {};
    SIDES.forEach(function (side) {
      layers[side] = {
        layer: part(side + '-layer'), image: part(side + '-image'), select: part(side + '-select'),
        tag: part(side + '-tag'), caption: part(side + '-caption')
      };
    });
    var state = {
      left: data.left, right: data.right, slider: 0.5, view: 'image', zoom: 1, x: 0, y: 0,
      exposure: Number(exposureInput.value) || 0
    };
    var naturalWidth = 0;

    function sourceOf(index) {
      var item = images[index];
      return state.view === 'error' ? (item.error || null) : item.image;
    }

    function render() {
      SIDES.forEach(function (side) {
        var parts = layers[side];
        var item = images[state[side]];
        var source = sourceOf(state[side]);
        var missing = source === null;
        if (!missing && parts.image.getAttribute('src') !== source) {
          parts.image.setAttribute('src', source);
        }
        parts.image.setAttribute('alt', item.label + (state.view === 'error' ? ' (error)' : ''));
        parts.layer.classList.toggle('sparselt-viewer-missing', missing);
        parts.image.style.transform = 'translate(' + (state.x * 100) + '%, ' + (state.y * 100) + '%) scale(' +
          state.zoom + ')';
        parts.layer.style.filter = state.view === 'image' && state.exposure !== 0 ?
          'url(#' + data.filter + ')' : '';
        parts.tag.textContent = item.label + (state.view === 'error' && !missing ? ' \u00b7 error' : '');
        parts.caption.textContent = '';
        var strong = document.createElement('strong');
        strong.textContent = item.label;
        parts.caption.appendChild(strong);
        if (item.caption) {
          parts.caption.appendChild(document.createTextNode(': ' + item.caption));
        }
        if (parts.select.value !== String(state[side])) {
          parts.select.value = String(state[side]);
        }
        root.setAttribute('data-' + side, item.label);
      });
      var percent = state.slider * 100;
      layers.left.layer.style.clipPath = 'inset(0 ' + (100 - percent) + '% 0 0)';
      divider.style.left = percent + '%';
      divider.setAttribute('aria-valuenow', String(Math.round(percent)));
      var gain = Math.pow(2, state.exposure);
      gains.forEach(function (element) {
        element.setAttribute('slope', rounded(gain));
      });
      exposureInput.disabled = state.view === 'error';
      exposureValue.textContent = (state.exposure >= 0 ? '+' : '\u2212') + Math.abs(state.exposure).toFixed(1) +
        ' stops (\u00d7' + (Math.round(gain * 100) / 100) + ')';
      zoomValue.textContent = '\u00d7' + (Math.round(state.zoom * 10) / 10);
      if (legend) {
        legend.hidden = state.view !== 'error';
      }
      var magnification = naturalWidth > 0 ? state.zoom * stage.clientWidth / naturalWidth : state.zoom;
      stage.classList.toggle('sparselt-viewer-pixelated', state.zoom > 1 || magnification > 1);
      stage.classList.toggle('sparselt-viewer-zoomed', state.zoom > 1);
      root.setAttribute('data-slider', rounded(state.slider));
      root.setAttribute('data-view', state.view);
      root.setAttribute('data-zoom', rounded(state.zoom));
      root.setAttribute('data-pan-x', rounded(state.x));
      root.setAttribute('data-pan-y', rounded(state.y));
      root.setAttribute('data-exposure', String(state.exposure));
    }

    function clampPan() {
      state.x = clamp(state.x, 1 - state.zoom, 0);
      state.y = clamp(state.y, 1 - state.zoom, 0);
    }

    /* Zoom by `factor` keeping the image point under (u, v), fractions of the stage, where it is. */
    function zoomAt(factor, u, v) {
      var zoom = clamp(state.zoom * factor, MINIMUM_ZOOM, MAXIMUM_ZOOM);
      var ratio = zoom / state.zoom;
      state.x = u - (u - state.x) * ratio;
      state.y = v - (v - state.y) * ratio;
      state.zoom = zoom;
      clampPan();
      render();
    }

    function reset() {
      state.zoom = 1;
      state.x = 0;
      state.y = 0;
      render();
    }

    function setSlider(value) {
      state.slider = clamp(value, 0, 1);
      render();
    }

    function fraction(event) {
      var box = stage.getBoundingClientRect();
      return {
        u: box.width > 0 ? (event.clientX - box.left) / box.width : 0.5,
        v: box.height > 0 ? (event.clientY - box.top) / box.height : 0.5, box: box
      };
    }

    /* A drag: the divider's (on the divider, or anywhere when not zoomed) or a pan; followed on window so
     * it continues outside the stage, and ended by pointerup or pointercancel. */
    function startDrag(event, moveDivider) {
      if (event.button !== undefined && event.button !== 0) {
        return;
      }
      event.preventDefault();
      event.stopPropagation();
      var start = fraction(event);
      var origin = {x: state.x, y: state.y};
      if (moveDivider) {
        setSlider(start.u);
      } else {
        stage.classList.add('sparselt-viewer-panning');
      }
      try {
        stage.focus({preventScroll: true});
      } catch (error) {
        /* an old browser without focus options: focus is a convenience only */
      }
      function move(moving) {
        var now = fraction(moving);
        if (moveDivider) {
          setSlider(now.u);
        } else {
          state.x = origin.x + (now.u - start.u);
          state.y = origin.y + (now.v - start.v);
          clampPan();
          render();
        }
      }
      function end() {
        window.removeEventListener('pointermove', move);
        window.removeEventListener('pointerup', end);
        window.removeEventListener('pointercancel', end);
        stage.classList.remove('sparselt-viewer-panning');
      }
      window.addEventListener('pointermove', move);
      window.addEventListener('pointerup', end);
      window.addEventListener('pointercancel', end);
    }

    divider.addEventListener('pointerdown', function (event) {
      startDrag(event, true);
    });
    stage.addEventListener('pointerdown', function (event) {
      startDrag(event, state.zoom <= MINIMUM_ZOOM);
    });
    stage.addEventListener('wheel', function (event) {
      var scale = event.deltaMode === 1 ? 33 : (event.deltaMode === 2 ? 400 : 1);
      var delta = clamp(event.deltaY * scale, -300, 300);
      var factor = Math.pow(2, -delta / 300);
      if (delta === 0 || (factor < 1 && state.zoom <= MINIMUM_ZOOM) || (factor > 1 && state.zoom >= MAXIMUM_ZOOM)) {
        return; /* nothing to zoom: let the page scroll */
      }
      event.preventDefault();
      var at = fraction(event);
      zoomAt(factor, clamp(at.u, 0, 1), clamp(at.v, 0, 1));
    }, {passive: false});
    stage.addEventListener('dblclick', function (event) {
      event.preventDefault();
      reset();
    });
    stage.addEventListener('keydown', function (event) {
      var step = event.shiftKey ? FINE_KEY_STEP : KEY_STEP;
      var handled = true;
      if (event.key === 'ArrowLeft') {
        setSlider(state.slider - step);
      } else if (event.key === 'ArrowRight') {
        setSlider(state.slider + step);
      } else if (event.key === 'Home') {
        setSlider(0);
      } else if (event.key === 'End') {
        setSlider(1);
      } else if (event.key === '+' || event.key === '=') {
        zoomAt(BUTTON_ZOOM, 0.5, 0.5);
      } else if (event.key === '-' || event.key === '_') {
        zoomAt(1 / BUTTON_ZOOM, 0.5, 0.5);
      } else if (event.key === '0') {
        reset();
      } else {
        handled = false;
      }
      if (handled) {
        event.preventDefault();
      }
    });
    SIDES.forEach(function (side) {
      layers[side].select.addEventListener('change', function () {
        var index = Number(layers[side].select.value);
        if (index >= 0 && index < images.length) {
          state[side] = index;
          render();
        }
      });
    });
    errorToggle.addEventListener('change', function () {
      state.view = errorToggle.checked ? 'error' : 'image';
      render();
    });
    function onExposure() {
      var value = Number(exposureInput.value);
      state.exposure = isFinite(value) ? value : 0;
      render();
    }
    exposureInput.addEventListener('input', onExposure);
    exposureInput.addEventListener('change', onExposure);
    part('zoom-in').addEventListener('click', function () {
      zoomAt(BUTTON_ZOOM, 0.5, 0.5);
    });
    part('zoom-out').addEventListener('click', function () {
      zoomAt(1 / BUTTON_ZOOM, 0.5, 0.5);
    });
    part('reset').addEventListener('click', reset);

    /* Load every image and error image once: data-ready when all have loaded or failed, data-broken the failed
     * ones (in the order of the data), a visible warning for those and for images of different sizes. */
    var sources = [];
    images.forEach(function (item) {
      [item.image, item.error].forEach(function (source) {
        if (source && sources.indexOf(source) < 0) {
          sources.push(source);
        }
      });
    });
    var sizes = {};
    var failed = {};
    var pending = sources.length;
    function settle() {
      pending -= 1;
      if (pending > 0) {
        return;
      }
      var broken = sources.filter(function (source) {
        return failed[source];
      });
      var distinct = {};
      sources.forEach(function (source) {
        if (sizes[source]) {
          distinct[sizes[source]] = (distinct[sizes[source]] || []).concat([source]);
        }
      });
      var messages = [];
      if (broken.length) {
        messages.push('Could not load: ' + broken.join(', ') + '.');
      }
      if (Object.keys(distinct).length > 1) {
        messages.push('The images differ in size: ' + Object.keys(distinct).map(function (size) {
          return size + ' (' + distinct[size].join(', ') + ')';
        }).join('; ') + '.');
      }
      warning.textContent = messages.join(' ');
      warning.hidden = messages.length === 0;
      var reference = sizes[images[0].image] || sizes[sources.filter(function (source) {
        return sizes[source];
      })[0]];
      if (reference) {
        naturalWidth = Number(reference.split('\u00d7')[0]);
        stage.style.width = Math.max(naturalWidth, MINIMUM_DISPLAY_WIDTH) + 'px';
        part('captions').style.maxWidth = stage.style.width;
      }
      render();
      root.setAttribute('data-broken', broken.join(' '));
      root.setAttribute('data-ready', 'true');
      root.dispatchEvent(new CustomEvent('sparselt-viewer-ready', {bubbles: true, detail: {broken: broken}}));
    }
    render();
    sources.forEach(function (source) {
      var probe = new Image();
      probe.onload = function () {
        sizes[source] = probe.naturalWidth + '\u00d7' + probe.naturalHeight;
        settle();
      };
      probe.onerror = function () {
        failed[source] = true;
        settle();
      };
      probe.src = source;
    });
  }

  function initAll() {
    Array.prototype.forEach.call(document.querySelectorAll('.sparselt-viewer'), init);
  }

  window.sparseltViewer = {init: init};
  if (document.readyState === 'loading') {
    document.addEventListener('DOMContentLoaded', initAll);
  } else {
    initAll();
  }
}());
