// The plugin choices (Tracer, Converter): a select of the plugins of a kind (GET /plugins, in the store) and a
// parameter form generated from the chosen one's JSON schema (numbers, integers, enums, booleans, strings). The
// service validates again; this only offers the right inputs with their defaults. Kinds: "tracer" and
// "converter", whose controls are #<kind>-select and #<kind>-params.
import { state } from "../store.js";
import { $ } from "./dom.js";

const PREFERRED = ["geodesic", "nearest-neighbor"];

/** Fill the select of a kind with its plugins (choosing a preferred one) and show the chosen one's form. */
export function showPlugins(kind) {
  const select = $(`${kind}-select`);
  const plugins = state.plugins[kind];
  select.replaceChildren(...plugins.map((p) => Object.assign(new Option(p.name, p.name), { title: p.description })));
  const preferred = plugins.find((p) => PREFERRED.includes(p.name));
  if (preferred) select.value = preferred.name;
  showParameters(kind);
}

/** The form of the chosen plugin: one input per schema property. */
export function showParameters(kind) {
  const container = $(`${kind}-params`);
  container.replaceChildren();
  const properties = Object.entries(chosenSchema(kind)?.properties ?? {});
  for (const [name, property] of properties) {
    const field = document.createElement("label");
    field.title = property.description ?? "";
    field.append(`${property.title ?? name} `);
    const input = inputFor(property);
    input.name = name;
    field.append(input);
    container.append(field);
  }
  container.hidden = properties.length === 0;
}

/** The chosen plugin of a kind and its parameters as the form says: { name, params }. */
export function pluginChoice(kind) {
  const name = $(`${kind}-select`).value;
  const params = {};
  const inputs = $(`${kind}-params`).querySelectorAll("input, select");
  for (const [propertyName, property] of Object.entries(chosenSchema(kind)?.properties ?? {})) {
    const input = [...inputs].find((element) => element.name === propertyName);
    const value = input && valueOf(input, property);
    if (value !== undefined) params[propertyName] = value;
  }
  return { name, params };
}

function chosenSchema(kind) {
  return state.plugins[kind].find((p) => p.name === $(`${kind}-select`).value)?.parameters;
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
