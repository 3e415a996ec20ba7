// The plugin choices (Tracer, Converter): a select of the plugins of a kind (GET /plugins, in the store) and a
// parameter form generated from the chosen one's JSON schema (numbers, integers, enums, booleans, strings). The
// service validates again; this only offers the right inputs with their defaults. Kinds: "tracer" and
// "converter", whose controls are #<controls>-select and #<controls>-params (controls: the kind itself, unless a
// second choice of the kind names its own, as the Collections panel's "run-converter").
import { state } from "../store.js";
import { $ } from "./dom.js";

const PREFERRED = ["geodesic", "nearest-neighbor"];
// A form with more parameters than this folds them under "Advanced parameters": rhm's fifteen pushed Refine off the
// panel, and each has a default that works.
const SHOWN_PARAMETERS = 4;

/** Fill the select of a kind with its plugins (choosing a preferred one) and show the chosen one's form. */
export function showPlugins(kind, controls = kind) {
  const select = $(`${controls}-select`);
  const plugins = state.plugins[kind];
  select.replaceChildren(...plugins.map((p) => Object.assign(new Option(p.name, p.name), { title: p.description })));
  const preferred = plugins.find((p) => PREFERRED.includes(p.name));
  if (preferred) select.value = preferred.name;
  showParameters(kind, controls);
}

/** The form of the chosen plugin: one input per schema property, with a readable label, its current value (the
 * default until changed) and what it means, folded under a closed "Advanced parameters" when there are many. A
 * nested parameter set (e.g. rhm's zoomout start) keeps its defaults. */
export function showParameters(kind, controls = kind) {
  const container = $(`${controls}-params`);
  container.replaceChildren();
  const properties = Object.entries(chosenSchema(kind, controls)?.properties ?? {});
  let fields = container;
  if (properties.length > SHOWN_PARAMETERS) {
    fields = Object.assign(document.createElement("details"), { className: "advanced" });
    const summary = document.createElement("summary");
    summary.textContent = `Advanced parameters (${properties.length}, defaults work)`;
    fields.append(summary);
    container.append(fields);
  }
  for (const [name, property] of properties) {
    const field = document.createElement("label");
    field.title = property.description ?? "";
    field.append(`${readable(name, property)} `);
    if (property.$ref) {
      field.append(Object.assign(document.createElement("span"), { className: "param-fixed", textContent: "defaults" }));
    } else {
      const input = inputFor(valueSchema(property));
      input.name = name;
      field.append(input);
    }
    const help = Object.assign(document.createElement("small"), { className: "param-help" });
    help.textContent = property.description ?? "";
    field.append(help);
    fields.append(field);
  }
  container.hidden = properties.length === 0;
}

/** "k_init" -> "k init", unless the schema gives a title of its own words (pydantic's are the name capitalised). */
function readable(name, property) {
  const words = name.replaceAll("_", " ");
  const generated = property.title?.toLowerCase() === words;
  return property.title && !generated ? property.title : words.charAt(0).toUpperCase() + words.slice(1);
}

/** The schema of the value an input holds: an optional value (anyOf with null) takes its other type; its default
 * stays (null: the input is left empty, saying so). */
function valueSchema(property) {
  const other = property.anyOf?.find((option) => option.type !== "null");
  return other ? { ...other, default: property.default, optional: true } : property;
}

/** The chosen plugin of a kind and its parameters as the form says: { name, params }. */
export function pluginChoice(kind, controls = kind) {
  const name = $(`${controls}-select`).value;
  const params = {};
  const inputs = $(`${controls}-params`).querySelectorAll("input, select");
  for (const [propertyName, property] of Object.entries(chosenSchema(kind, controls)?.properties ?? {})) {
    const input = [...inputs].find((element) => element.name === propertyName);
    const value = input && valueOf(input, valueSchema(property));
    if (value !== undefined) params[propertyName] = value;
  }
  return { name, params };
}

/** The chosen tracer and its parameters, as a curve spec names them. */
export function tracerChoice() {
  const { name, params } = pluginChoice("tracer");
  return { tracer: name, tracer_params: params };
}

function chosenSchema(kind, controls) {
  return state.plugins[kind].find((p) => p.name === $(`${controls}-select`).value)?.parameters;
}

function inputFor(property) {
  if (property.enum) {
    const select = document.createElement("select");
    for (const option of property.enum) select.append(new Option(String(option), String(option)));
    select.value = String(property.default ?? property.enum[0]);
    return select;
  }
  const input = document.createElement("input");
  if (property.type === "boolean") {
    input.type = "checkbox";
    input.checked = Boolean(property.default);
  } else if (property.type === "number" || property.type === "integer") {
    input.type = "number";
    input.step = property.type === "integer" ? "1" : "any";
    for (const bound of ["minimum", "maximum"]) {
      if (property[bound] !== undefined) input[bound.slice(0, 3)] = String(property[bound]);
    }
    input.value = property.default ?? "";
    if (property.optional) input.placeholder = "off (default)";
  } else {
    input.type = "text";
    input.value = property.default ?? "";
  }
  return input;
}

/** An input's value as the schema types it; undefined for an empty number or text (the default applies). */
function valueOf(input, property) {
  if (property.enum) return property.enum.find((option) => String(option) === input.value);
  if (property.type === "boolean") return input.checked;
  if (property.type === "number" || property.type === "integer") {
    return input.value === "" ? undefined : Number(input.value);
  }
  return input.value === "" ? undefined : input.value;
}
